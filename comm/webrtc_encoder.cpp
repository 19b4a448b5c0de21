#include "comm/webrtc_encoder.hpp"

#include <gst/app/gstappsink.h>
#include <gst/app/gstappsrc.h>
#include <gst/gst.h>
#include <gst/video/video.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <mutex>

#include "core/error.hpp"

namespace kestrel::comm {

int default_kbps(int width, int height) {
  const double pixels = static_cast<double>(width) * height;
  return std::max(500, static_cast<int>(3000.0 * pixels / (1280.0 * 720.0)));
}

void init_gstreamer() {
  static std::once_flag once;
  static std::string missing;
  std::call_once(once, [] {
    gst_init(nullptr, nullptr);
    for (const char* name : {"appsrc", "appsink", "x264enc", "rtph264pay", "webrtcbin", "nicesrc",
                             "dtlssrtpenc", "srtpenc", "rtpbin"}) {
      GstElementFactory* f = gst_element_factory_find(name);
      if (!f) {
        missing += missing.empty() ? name : std::string(", ") + name;
      } else {
        gst_object_unref(f);
      }
    }
  });
  if (!missing.empty()) {
    throw Error(
        "GStreamer elements missing: " + missing +
        " (gstreamer1.0-plugins-{base,good,bad,ugly} and gstreamer1.0-nice: scripts/setup)");
  }
}

std::string h264_encoder_launch(const EncoderSettings& s) {
  return "x264enc name=enc tune=zerolatency speed-preset=ultrafast threads=1 bitrate=" +
         std::to_string(s.kbps) + " vbv-buf-capacity=300 key-int-max=" +
         std::to_string(std::max(1, s.fps * s.keyframe_interval_s)) +
         " ! video/x-h264,profile=constrained-baseline,stream-format=avc,alignment=au";
}

namespace {

std::string raw_caps(const EncoderSettings& s) {
  return "video/x-raw,format=I420,width=" + std::to_string(s.width) +
         ",height=" + std::to_string(s.height) + ",framerate=" + std::to_string(s.fps) + "/1";
}

}  // namespace

struct H264Encoder::Impl {
  EncoderSettings settings;
  GstElement* pipeline = nullptr;
  GstElement* src = nullptr;
  GstElement* enc = nullptr;
  GstElement* sink = nullptr;
  std::uint64_t frames = 0;
};

H264Encoder::H264Encoder(EncoderSettings settings) : impl_(std::make_unique<Impl>()) {
  init_gstreamer();
  impl_->settings = settings;
  const std::string launch = "appsrc name=src is-live=false format=time caps=\"" +
                             raw_caps(settings) + "\" ! " + h264_encoder_launch(settings) +
                             " ! appsink name=sink sync=false max-buffers=64";
  GError* err = nullptr;
  impl_->pipeline = gst_parse_launch(launch.c_str(), &err);
  if (err) {
    const std::string why = err->message;
    g_error_free(err);
    if (impl_->pipeline) gst_object_unref(impl_->pipeline);
    throw Error("H.264 encoder pipeline '" + launch + "': " + why);
  }
  impl_->src = gst_bin_get_by_name(GST_BIN(impl_->pipeline), "src");
  impl_->enc = gst_bin_get_by_name(GST_BIN(impl_->pipeline), "enc");
  impl_->sink = gst_bin_get_by_name(GST_BIN(impl_->pipeline), "sink");
  if (gst_element_set_state(impl_->pipeline, GST_STATE_PLAYING) == GST_STATE_CHANGE_FAILURE) {
    throw Error("H.264 encoder pipeline refused to start");
  }
}

H264Encoder::~H264Encoder() {
  gst_element_set_state(impl_->pipeline, GST_STATE_NULL);
  gst_object_unref(impl_->src);
  gst_object_unref(impl_->enc);
  gst_object_unref(impl_->sink);
  gst_object_unref(impl_->pipeline);
}

std::optional<H264Encoder::Encoded> H264Encoder::encode(const std::vector<std::uint8_t>& i420) {
  const auto& s = impl_->settings;
  const std::size_t need = static_cast<std::size_t>(s.width) * s.height * 3 / 2;
  if (i420.size() != need) {
    throw Error("H264Encoder: frame of " + std::to_string(i420.size()) + " bytes, expected " +
                std::to_string(need));
  }
  GstBuffer* buf = gst_buffer_new_allocate(nullptr, need, nullptr);
  gst_buffer_fill(buf, 0, i420.data(), need);
  const GstClockTime frame_ns = GST_SECOND / static_cast<GstClockTime>(std::max(1, s.fps));
  GST_BUFFER_PTS(buf) = impl_->frames * frame_ns;
  GST_BUFFER_DURATION(buf) = frame_ns;
  ++impl_->frames;
  const auto t0 = std::chrono::steady_clock::now();
  if (gst_app_src_push_buffer(GST_APP_SRC(impl_->src), buf) != GST_FLOW_OK) return std::nullopt;
  GstSample* sample = gst_app_sink_try_pull_sample(GST_APP_SINK(impl_->sink), GST_SECOND);
  if (!sample) return std::nullopt;
  Encoded out;
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  GstBuffer* b = gst_sample_get_buffer(sample);
  out.keyframe = !GST_BUFFER_FLAG_IS_SET(b, GST_BUFFER_FLAG_DELTA_UNIT);
  out.bytes.resize(gst_buffer_get_size(b));
  gst_buffer_extract(b, 0, out.bytes.data(), out.bytes.size());
  gst_sample_unref(sample);
  return out;
}

void H264Encoder::request_keyframe() {
  GstPad* pad = gst_element_get_static_pad(impl_->enc, "src");
  gst_pad_send_event(pad,
                     gst_video_event_new_upstream_force_key_unit(GST_CLOCK_TIME_NONE, TRUE, 0));
  gst_object_unref(pad);
}

void H264Encoder::set_kbps(int kbps) {
  g_object_set(impl_->enc, "bitrate", static_cast<guint>(std::max(1, kbps)), nullptr);
}

std::string H264Encoder::output_caps() const {
  GstPad* pad = gst_element_get_static_pad(impl_->sink, "sink");
  GstCaps* caps = gst_pad_get_current_caps(pad);
  gst_object_unref(pad);
  if (!caps) return {};
  gchar* text = gst_caps_to_string(caps);
  std::string out = text;
  g_free(text);
  gst_caps_unref(caps);
  return out;
}

}  // namespace kestrel::comm
