#include "comm/webrtc_sender.hpp"

#define GST_USE_UNSTABLE_API  // gst/webrtc is "unstable" API in 1.22
#include <gst/app/gstappsrc.h>
#include <gst/gst.h>
#include <gst/sdp/sdp.h>
#include <gst/video/video.h>
#include <gst/webrtc/webrtc.h>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <map>
#include <mutex>

#include "comm/webrtc_bitrate.hpp"
#include "comm/webrtc_encoder.hpp"
#include "core/error.hpp"

namespace kestrel::comm {
namespace {

using Clock = std::chrono::steady_clock;

// What every viewer's callbacks share with the sender; kept alive by the callbacks themselves,
// so a late GStreamer callback never sees a destroyed sender.
struct Shared {
  WebRtcSender::SendFn send;
  std::atomic<std::uint64_t> offers{0}, answers{0}, candidates_out{0}, candidates_in{0};
};

struct Viewer {
  std::string id;
  bool overlay = false;
  std::shared_ptr<Shared> shared;
  EncoderSettings enc_settings;

  // Held while the signaling thread uses the elements; close() takes it too. GStreamer's own
  // threads never take it (close() waits for them while holding it).
  std::mutex life;
  bool closed = false;
  std::atomic<bool> closing{false};
  GstElement* pipeline = nullptr;
  GstElement* src = nullptr;
  GstElement* enc = nullptr;
  GstElement* webrtc = nullptr;

  std::atomic<bool> offer_started{false}, offered{false}, connected{false}, failed{false};
  Clock::time_point created = Clock::now();
  std::atomic<Clock::rep> last_heard{Clock::now().time_since_epoch().count()};
  Clock::time_point next_rate = Clock::now();

  std::atomic<std::uint64_t> frames{0}, bytes{0}, keyframes{0}, requests{0};
  std::atomic<int> encoder_tid{0}, encoder_nice{0};
  std::mutex timing;  // encode timing and the rate controller
  std::deque<Clock::time_point> in_flight;
  std::deque<double> encode_ms;
  BitrateController rate{1000, 300};

  ~Viewer() { close(); }

  void close() {
    std::lock_guard lock(life);
    if (closed) return;
    closed = true;
    closing = true;
    if (pipeline) {
      // Joins the streaming, webrtcbin and libnice threads: no callback runs after this.
      gst_element_set_state(pipeline, GST_STATE_NULL);
      gst_object_unref(src);
      gst_object_unref(enc);
      gst_object_unref(webrtc);
      gst_object_unref(pipeline);
      pipeline = src = enc = webrtc = nullptr;
    }
  }

  void send(const std::string& json) const {
    if (shared->send) shared->send(id, json);
  }
};

using ViewerPtr = std::shared_ptr<Viewer>;

// GLib user data holding a strong reference to the viewer for as long as the closure lives.
gpointer hold(const ViewerPtr& v) { return new ViewerPtr(v); }
void release(gpointer p, GClosure* = nullptr) { delete static_cast<ViewerPtr*>(p); }
void release_notify(gpointer p) { delete static_cast<ViewerPtr*>(p); }
Viewer& viewer_of(gpointer p) { return **static_cast<ViewerPtr*>(p); }

void on_ice_candidate(GstElement*, guint mline, gchar* candidate, gpointer ud) {
  Viewer& v = viewer_of(ud);
  if (v.closing || !candidate) return;
  ++v.shared->candidates_out;
  v.send(candidate_json(static_cast<int>(mline), candidate));
}

void on_connection_state(GObject* webrtc, GParamSpec*, gpointer ud) {
  Viewer& v = viewer_of(ud);
  GstWebRTCPeerConnectionState state = GST_WEBRTC_PEER_CONNECTION_STATE_NEW;
  g_object_get(webrtc, "connection-state", &state, nullptr);
  if (state == GST_WEBRTC_PEER_CONNECTION_STATE_CONNECTED) v.connected = true;
  if (state == GST_WEBRTC_PEER_CONNECTION_STATE_FAILED ||
      state == GST_WEBRTC_PEER_CONNECTION_STATE_CLOSED) {
    v.connected = false;
    v.failed = true;
  }
}

void on_ice_state(GObject* webrtc, GParamSpec*, gpointer ud) {
  Viewer& v = viewer_of(ud);
  GstWebRTCICEConnectionState state = GST_WEBRTC_ICE_CONNECTION_STATE_NEW;
  g_object_get(webrtc, "ice-connection-state", &state, nullptr);
  if (state == GST_WEBRTC_ICE_CONNECTION_STATE_FAILED) v.failed = true;
}

void on_offer_created(GstPromise* promise, gpointer ud) {
  Viewer& v = viewer_of(ud);
  const GstStructure* reply = gst_promise_wait(promise) == GST_PROMISE_RESULT_REPLIED
                                  ? gst_promise_get_reply(promise)
                                  : nullptr;
  GstWebRTCSessionDescription* offer = nullptr;
  if (reply)
    gst_structure_get(reply, "offer", GST_TYPE_WEBRTC_SESSION_DESCRIPTION, &offer, nullptr);
  gst_promise_unref(promise);
  if (!offer || v.closing) {
    if (offer) gst_webrtc_session_description_free(offer);
    if (!offer) v.send(error_json("the sender could not create an offer"));
    if (!offer) v.failed = true;
    return;
  }
  g_signal_emit_by_name(v.webrtc, "set-local-description", offer, nullptr);
  gchar* text = gst_sdp_message_as_text(offer->sdp);
  const auto& s = v.enc_settings;
  int kbps = 0;
  {
    std::lock_guard lock(v.timing);
    kbps = v.rate.kbps();
  }
  v.send(offer_json(text, s.width, s.height, s.fps, kbps, v.overlay));
  g_free(text);
  gst_webrtc_session_description_free(offer);
  v.offered = true;
  ++v.shared->offers;
}

// Receiver reports (RTCP RR, as webrtcbin's "remote-inbound-rtp" stats) -> the encoder's rate.
gboolean stats_field(GQuark, const GValue* value, gpointer data) {
  auto* out = static_cast<std::pair<double, double>*>(data);
  if (!GST_VALUE_HOLDS_STRUCTURE(value)) return TRUE;
  const GstStructure* s = gst_value_get_structure(value);
  GstWebRTCStatsType type;
  if (!gst_structure_get(s, "type", GST_TYPE_WEBRTC_STATS_TYPE, &type, nullptr) ||
      type != GST_WEBRTC_STATS_REMOTE_INBOUND_RTP) {
    return TRUE;
  }
  gst_structure_get_double(s, "fraction-lost", &out->first);
  gst_structure_get_double(s, "round-trip-time", &out->second);
  return TRUE;
}

void on_stats(GstPromise* promise, gpointer ud) {
  Viewer& v = viewer_of(ud);
  std::pair<double, double> loss_rtt{-1.0, -1.0};
  if (gst_promise_wait(promise) == GST_PROMISE_RESULT_REPLIED) {
    if (const GstStructure* reply = gst_promise_get_reply(promise)) {
      gst_structure_foreach(reply, stats_field, &loss_rtt);
    }
  }
  gst_promise_unref(promise);
  if (v.closing || loss_rtt.first < 0) return;  // no receiver report yet
  int kbps = 0, before = 0;
  {
    std::lock_guard lock(v.timing);
    before = v.rate.kbps();
    kbps = v.rate.update(loss_rtt.first, loss_rtt.second);
  }
  if (kbps != before) g_object_set(v.enc, "bitrate", static_cast<guint>(kbps), nullptr);
}

int this_thread_id() { return static_cast<int>(syscall(SYS_gettid)); }

// The nice value of the calling thread (PRIO_PROCESS with a tid addresses one thread on Linux).
int this_thread_nice() {
  errno = 0;
  const int n = getpriority(PRIO_PROCESS, static_cast<id_t>(this_thread_id()));
  return errno ? 0 : n;
}

// Bus messages of a viewer's pipeline, handled synchronously in the thread that posts them.
// STREAM_STATUS/ENTER is posted by each streaming thread as it starts its loop: the place to
// lower that thread's priority (VideoOptions::stream_nice). Nothing reads the bus otherwise,
// so every message is dropped here rather than piling up for the pipeline's lifetime; errors
// are printed (a failing peer is noticed by webrtcbin's connection state).
GstBusSyncReply on_bus_message(GstBus*, GstMessage* msg, gpointer nice_value) {
  const int nice_to = GPOINTER_TO_INT(nice_value);
  if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_STREAM_STATUS && nice_to > 0) {
    GstStreamStatusType type = GST_STREAM_STATUS_TYPE_CREATE;
    GstElement* owner = nullptr;
    gst_message_parse_stream_status(msg, &type, &owner);
    if (type == GST_STREAM_STATUS_TYPE_ENTER && this_thread_nice() < nice_to) {
      if (setpriority(PRIO_PROCESS, static_cast<id_t>(this_thread_id()), nice_to) != 0) {
        std::perror("kestrel video: setpriority of a streaming thread");
      }
    }
  } else if (GST_MESSAGE_TYPE(msg) == GST_MESSAGE_ERROR) {
    GError* err = nullptr;
    gchar* debug = nullptr;
    gst_message_parse_error(msg, &err, &debug);
    std::fprintf(stderr, "kestrel video: %s: %s\n", GST_OBJECT_NAME(GST_MESSAGE_SRC(msg)),
                 err ? err->message : "error");
    if (err) g_error_free(err);
    g_free(debug);
  }
  return GST_BUS_DROP;
}

GstPadProbeReturn on_encoder_in(GstPad*, GstPadProbeInfo* info, gpointer ud) {
  Viewer& v = viewer_of(ud);
  if (GST_PAD_PROBE_INFO_BUFFER(info)) {
    // The encoder runs in the thread that pushes into its sink pad: this one.
    if (v.encoder_tid == 0) {
      v.encoder_nice = this_thread_nice();
      v.encoder_tid = this_thread_id();
    }
    std::lock_guard lock(v.timing);
    v.in_flight.push_back(Clock::now());
    while (v.in_flight.size() > 64) v.in_flight.pop_front();
  }
  return GST_PAD_PROBE_OK;
}

GstPadProbeReturn on_encoder_out(GstPad*, GstPadProbeInfo* info, gpointer ud) {
  Viewer& v = viewer_of(ud);
  if (info->type & GST_PAD_PROBE_TYPE_EVENT_UPSTREAM) {
    // PLI / FIR from the browser arrive here as force-key-unit events, as do our own requests.
    if (GstEvent* e = GST_PAD_PROBE_INFO_EVENT(info); e && gst_video_event_is_force_key_unit(e)) {
      ++v.requests;
    }
    return GST_PAD_PROBE_OK;
  }
  GstBuffer* b = GST_PAD_PROBE_INFO_BUFFER(info);
  if (!b) return GST_PAD_PROBE_OK;
  const auto now = Clock::now();
  ++v.frames;
  v.bytes += gst_buffer_get_size(b);
  if (!GST_BUFFER_FLAG_IS_SET(b, GST_BUFFER_FLAG_DELTA_UNIT)) ++v.keyframes;
  // In order, one out per one in (zerolatency: no lookahead, no B-frames, and nothing drops
  // between the encoder's pads). PTS cannot pair them: x264enc shifts its output by min-pts.
  std::lock_guard lock(v.timing);
  if (!v.in_flight.empty()) {
    v.encode_ms.push_back(
        std::chrono::duration<double, std::milli>(now - v.in_flight.front()).count());
    v.in_flight.pop_front();
    while (v.encode_ms.size() > 300) v.encode_ms.pop_front();
  }
  return GST_PAD_PROBE_OK;
}

bool caps_complete(GstElement* webrtc) {
  GstPad* pad = gst_element_get_static_pad(webrtc, "sink_0");
  if (!pad) return false;
  GstCaps* caps = gst_pad_get_current_caps(pad);
  gst_object_unref(pad);
  if (!caps) return false;
  const GstStructure* s = gst_caps_get_structure(caps, 0);
  const bool ok = gst_structure_has_field(s, "profile-level-id") &&
                  gst_structure_has_field(s, "sprop-parameter-sets");
  gst_caps_unref(caps);
  return ok;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5)];
}

GstBuffer* wrap(std::shared_ptr<const std::vector<std::uint8_t>> frame) {
  auto* holder = new std::shared_ptr<const std::vector<std::uint8_t>>(std::move(frame));
  auto* data = const_cast<std::uint8_t*>((*holder)->data());
  const gsize size = (*holder)->size();
  return gst_buffer_new_wrapped_full(
      GST_MEMORY_FLAG_READONLY, data, size, 0, size, holder,
      [](gpointer p) { delete static_cast<std::shared_ptr<const std::vector<std::uint8_t>>*>(p); });
}

}  // namespace

void parse_video_size(const std::string& text, const std::string& flag, VideoOptions& options) {
  int w = 0, h = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < kStampWidth ||
      h < kStampHeight || w > 1920 || h > 1080 || w % 2 || h % 2) {
    throw Error::at("command line", 0, flag,
                    "'" + text + "': expected WIDTHxHEIGHT, even, up to 1920x1080 (e.g. 1280x720)");
  }
  options.width = w;
  options.height = h;
}

struct WebRtcSender::Impl {
  VideoOptions opt;
  std::shared_ptr<Shared> shared = std::make_shared<Shared>();
  mutable std::mutex mutex;  // viewers, pending hellos, counts
  std::map<std::string, ViewerPtr> viewers;
  std::map<std::string, SignalMsg> hellos;  // created on the frame thread
  std::vector<ViewerPtr> doomed;            // closed on the frame thread
  std::atomic<std::uint64_t> frames_in{0}, signals_ok{0}, created{0}, closed{0};
  std::atomic<std::uint64_t> rejected[kSignalErrorCount] = {};
  std::uint16_t frame_number = 0;

  void reject(const std::string& viewer, SignalError e, const std::string& detail) {
    ++rejected[static_cast<int>(e)];
    if (valid_viewer_id(viewer) && shared->send) {
      shared->send(viewer, error_json(std::string(to_string(e)) + ": " + detail));
    }
  }

  // A viewer whose pipeline failed half-built is closed here: its callbacks hold it alive.
  ViewerPtr create(const std::string& id, const SignalMsg& hello) {
    auto v = std::make_shared<Viewer>();
    try {
      build(v, id, hello);
    } catch (...) {
      v->close();
      throw;
    }
    ++created;
    return v;
  }

  void build(const ViewerPtr& v, const std::string& id, const SignalMsg& hello) {
    v->id = id;
    v->overlay = hello.overlay;
    v->shared = shared;
    EncoderSettings es;
    es.width = opt.width;
    es.height = opt.height;
    es.fps = opt.fps;
    const int target = opt.kbps > 0 ? opt.kbps : default_kbps(opt.width, opt.height);
    es.kbps = hello.max_kbps > 0 ? std::min(target, hello.max_kbps) : target;
    v->enc_settings = es;
    v->rate = BitrateController(es.kbps, opt.min_kbps);
    const std::string launch =
        "appsrc name=src is-live=true format=time do-timestamp=true max-buffers=1 "
        "leaky-type=downstream caps=\"video/x-raw,format=I420,width=" +
        std::to_string(es.width) + ",height=" + std::to_string(es.height) +
        ",framerate=" + std::to_string(es.fps) + "/1\" ! " + h264_encoder_launch(es) +
        " ! rtph264pay config-interval=-1 aggregate-mode=zero-latency pt=96 ! "
        "application/x-rtp,media=video,encoding-name=H264,payload=96 ! "
        "webrtcbin name=webrtc bundle-policy=max-bundle";
    GError* err = nullptr;
    v->pipeline = gst_parse_launch(launch.c_str(), &err);
    if (err) {
      const std::string why = err->message;
      g_error_free(err);
      if (v->pipeline) gst_object_unref(v->pipeline);
      v->pipeline = nullptr;
      throw Error("video pipeline: " + why);
    }
    v->src = gst_bin_get_by_name(GST_BIN(v->pipeline), "src");
    v->enc = gst_bin_get_by_name(GST_BIN(v->pipeline), "enc");
    v->webrtc = gst_bin_get_by_name(GST_BIN(v->pipeline), "webrtc");
    GstBus* bus = gst_pipeline_get_bus(GST_PIPELINE(v->pipeline));
    gst_bus_set_sync_handler(bus, on_bus_message, GINT_TO_POINTER(opt.stream_nice), nullptr);
    gst_object_unref(bus);

    GstWebRTCRTPTransceiver* trans = nullptr;
    g_signal_emit_by_name(v->webrtc, "get-transceiver", 0, &trans);
    if (!trans) throw Error("webrtcbin made no transceiver for the video pad");
    g_object_set(trans, "direction", GST_WEBRTC_RTP_TRANSCEIVER_DIRECTION_SENDONLY, "do-nack", TRUE,
                 nullptr);
    gst_object_unref(trans);

    // libnice skips loopback interfaces; "add-local-ip-address" is webrtcbin's wrapper of
    // nice_agent_add_local_address() on its NiceAgent, and once an address is added libnice
    // gathers on that address only: 127.0.0.1 and nothing else, no STUN, no TURN.
    GstWebRTCICE* ice = nullptr;
    g_object_get(v->webrtc, "ice-agent", &ice, nullptr);
    if (!ice) throw Error("webrtcbin has no ICE agent");
    gboolean added = FALSE;
    g_signal_emit_by_name(ice, "add-local-ip-address", "127.0.0.1", &added);
    if (g_object_class_find_property(G_OBJECT_GET_CLASS(ice), "ice-tcp")) {
      g_object_set(ice, "ice-tcp", FALSE, nullptr);
    }
    gst_object_unref(ice);
    if (!added) throw Error("libnice refused 127.0.0.1 as a local address");

    g_signal_connect_data(v->webrtc, "on-ice-candidate", G_CALLBACK(on_ice_candidate), hold(v),
                          release, GConnectFlags(0));
    g_signal_connect_data(v->webrtc, "notify::connection-state", G_CALLBACK(on_connection_state),
                          hold(v), release, GConnectFlags(0));
    g_signal_connect_data(v->webrtc, "notify::ice-connection-state", G_CALLBACK(on_ice_state),
                          hold(v), release, GConnectFlags(0));
    GstPad* enc_sink = gst_element_get_static_pad(v->enc, "sink");
    gst_pad_add_probe(enc_sink, GST_PAD_PROBE_TYPE_BUFFER, on_encoder_in, hold(v), release_notify);
    gst_object_unref(enc_sink);
    GstPad* enc_src = gst_element_get_static_pad(v->enc, "src");
    gst_pad_add_probe(
        enc_src, GstPadProbeType(GST_PAD_PROBE_TYPE_BUFFER | GST_PAD_PROBE_TYPE_EVENT_UPSTREAM),
        on_encoder_out, hold(v), release_notify);
    gst_object_unref(enc_src);

    if (gst_element_set_state(v->pipeline, GST_STATE_PLAYING) == GST_STATE_CHANGE_FAILURE) {
      throw Error("video pipeline refused to start");
    }
  }

  // On the frame thread: new viewers in, dead ones out, offers once caps are complete, rates.
  void service() {
    std::map<std::string, SignalMsg> fresh;
    std::vector<ViewerPtr> dead;
    {
      std::lock_guard lock(mutex);
      fresh.swap(hellos);
      dead.swap(doomed);
    }
    for (auto& v : dead) v->close();
    closed += dead.size();
    dead.clear();
    for (const auto& [id, hello] : fresh) {
      ViewerPtr v;
      try {
        v = create(id, hello);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "kestrel video: viewer %s: %s\n", id.c_str(), e.what());
        if (shared->send) shared->send(id, error_json(e.what()));
        continue;
      }
      std::lock_guard lock(mutex);
      if (auto old = viewers.find(id); old != viewers.end()) dead.push_back(old->second);
      viewers[id] = v;
    }
    const auto now = Clock::now();
    {
      std::lock_guard lock(mutex);
      for (auto it = viewers.begin(); it != viewers.end();) {
        Viewer& v = *it->second;
        const auto heard = Clock::time_point(Clock::duration(v.last_heard.load()));
        const bool late = !v.connected && now - v.created > opt.connect_timeout;
        const bool silent = now - heard > opt.alive_timeout;
        if (v.failed || late || silent) {
          dead.push_back(it->second);
          it = viewers.erase(it);
        } else {
          ++it;
        }
      }
    }
    for (auto& v : dead) v->close();
    closed += dead.size();
    std::vector<ViewerPtr> live = snapshot();
    for (auto& v : live) {
      if (!v->offer_started && caps_complete(v->webrtc)) {
        v->offer_started = true;
        GstPromise* p = gst_promise_new_with_change_func(on_offer_created, hold(v), release_notify);
        g_signal_emit_by_name(v->webrtc, "create-offer", nullptr, p);
      }
      if (v->connected && now >= v->next_rate) {
        v->next_rate = now + opt.rate_period;
        GstPromise* p = gst_promise_new_with_change_func(on_stats, hold(v), release_notify);
        g_signal_emit_by_name(v->webrtc, "get-stats", nullptr, p);
      }
    }
  }

  std::vector<ViewerPtr> snapshot() const {
    std::lock_guard lock(mutex);
    std::vector<ViewerPtr> out;
    for (const auto& [id, v] : viewers) out.push_back(v);
    return out;
  }
};

WebRtcSender::WebRtcSender(VideoOptions options, SendFn send)
    : options_(options), impl_(std::make_unique<Impl>()) {
  init_gstreamer();
  if (options_.width % 2 || options_.height % 2 || options_.width < kStampWidth ||
      options_.height < kStampHeight || options_.fps <= 0) {
    throw Error("video: bad size or rate " + std::to_string(options_.width) + "x" +
                std::to_string(options_.height) + "@" + std::to_string(options_.fps));
  }
  if (const char* env = std::getenv("KESTREL_VIDEO_NICE"); env && *env) {
    options_.stream_nice = std::atoi(env);
  }
  options_.stream_nice = std::clamp(options_.stream_nice, 0, 19);
  impl_->opt = options_;
  impl_->shared->send = std::move(send);
}

WebRtcSender::~WebRtcSender() {
  std::vector<ViewerPtr> all;
  {
    std::lock_guard lock(impl_->mutex);
    for (auto& [id, v] : impl_->viewers) all.push_back(v);
    impl_->viewers.clear();
    for (auto& v : impl_->doomed) all.push_back(v);
    impl_->doomed.clear();
  }
  for (auto& v : all) v->close();
}

void WebRtcSender::count_reject(SignalError e) { ++impl_->rejected[static_cast<int>(e)]; }

bool WebRtcSender::handle(const std::string& viewer, std::span<const std::uint8_t> payload) {
  if (!valid_viewer_id(viewer)) {
    impl_->reject(viewer, SignalError::kBadTopic, "viewer id");
    return false;
  }
  auto parsed = parse_signal(payload);
  if (auto* r = std::get_if<SignalReject>(&parsed)) {
    impl_->reject(viewer, r->error, r->detail);
    return false;
  }
  const SignalMsg& m = std::get<SignalMsg>(parsed);
  ViewerPtr v;
  {
    std::lock_guard lock(impl_->mutex);
    if (m.kind == SignalKind::kHello) {
      // A repeated hello restarts that viewer (a page whose peer connection went bad).
      const bool known = impl_->viewers.count(viewer) || impl_->hellos.count(viewer);
      if (!known && impl_->viewers.size() + impl_->hellos.size() >= impl_->opt.max_viewers) {
        ++impl_->rejected[static_cast<int>(SignalError::kTooManyViewers)];
      } else {
        impl_->hellos[viewer] = m;
        ++impl_->signals_ok;
        return true;
      }
    } else if (auto it = impl_->viewers.find(viewer); it != impl_->viewers.end()) {
      v = it->second;
      if (m.kind == SignalKind::kBye) {
        impl_->doomed.push_back(v);
        impl_->viewers.erase(it);
        ++impl_->signals_ok;
        return true;
      }
    } else if (m.kind == SignalKind::kAlive && impl_->hellos.count(viewer)) {
      ++impl_->signals_ok;
      return true;
    } else {
      ++impl_->rejected[static_cast<int>(SignalError::kUnknownViewer)];
    }
  }
  if (!v) {
    if (m.kind == SignalKind::kHello) {
      if (impl_->shared->send) impl_->shared->send(viewer, error_json("too many viewers"));
    } else if (m.kind != SignalKind::kBye) {
      // Tells a page that outlived an agent restart to start over with a hello.
      if (impl_->shared->send) impl_->shared->send(viewer, error_json("unknown viewer"));
    }
    return false;
  }
  v->last_heard = Clock::now().time_since_epoch().count();
  std::lock_guard life(v->life);
  if (v->closed) return false;
  switch (m.kind) {
    case SignalKind::kAnswer: {
      GstSDPMessage* sdp = nullptr;
      gst_sdp_message_new(&sdp);
      if (gst_sdp_message_parse_buffer(reinterpret_cast<const guint8*>(m.sdp.data()),
                                       static_cast<guint>(m.sdp.size()), sdp) != GST_SDP_OK ||
          gst_sdp_message_medias_len(sdp) == 0) {
        gst_sdp_message_free(sdp);
        impl_->reject(viewer, SignalError::kBadSdp, "unparsable answer");
        return false;
      }
      const GstSDPMedia* media = gst_sdp_message_get_media(sdp, 0);
      if (gst_sdp_media_get_port(media) == 0) {
        // The browser refused the codec (e.g. a High-profile offer): say so, do not hang.
        gst_sdp_message_free(sdp);
        impl_->reject(viewer, SignalError::kBadSdp, "the answer rejects the video");
        v->failed = true;
        return false;
      }
      GstWebRTCSessionDescription* answer =
          gst_webrtc_session_description_new(GST_WEBRTC_SDP_TYPE_ANSWER, sdp);
      g_signal_emit_by_name(v->webrtc, "set-remote-description", answer, nullptr);
      gst_webrtc_session_description_free(answer);
      ++impl_->shared->answers;
      break;
    }
    case SignalKind::kCandidate: {
      g_signal_emit_by_name(v->webrtc, "add-ice-candidate", static_cast<guint>(m.mline),
                            m.candidate.c_str());
      ++impl_->shared->candidates_in;
      break;
    }
    case SignalKind::kKeyframe: {
      GstPad* pad = gst_element_get_static_pad(v->enc, "src");
      gst_pad_send_event(pad,
                         gst_video_event_new_upstream_force_key_unit(GST_CLOCK_TIME_NONE, TRUE, 0));
      gst_object_unref(pad);
      break;
    }
    default:
      break;  // alive: last_heard is all it does
  }
  ++impl_->signals_ok;
  return true;
}

void WebRtcSender::push_frame(const Image& image, std::int64_t capture_wall_ns,
                              const VideoOverlay* overlay) {
  ++impl_->frames_in;
  impl_->service();
  std::vector<ViewerPtr> live = impl_->snapshot();
  const FrameStamp stamp{static_cast<std::uint64_t>(capture_wall_ns / 1000), impl_->frame_number++};
  if (live.empty() || image.empty()) return;
  std::shared_ptr<const std::vector<std::uint8_t>> plain, drawn;
  for (auto& v : live) {
    auto& frame = v->overlay && overlay ? drawn : plain;
    if (!frame) {
      try {
        frame = std::make_shared<const std::vector<std::uint8_t>>(make_i420(
            image, options_.width, options_.height, v->overlay ? overlay : nullptr, stamp));
      } catch (const std::exception& e) {
        std::fprintf(stderr, "kestrel video: %s\n", e.what());
        return;
      }
    }
    std::lock_guard life(v->life);
    if (v->closed) continue;
    // Leaky appsrc holding one frame: an encoder starved of CPU (it runs at stream_nice) drops
    // the older frame, newest wins, instead of queueing latency or blocking this thread.
    gst_app_src_push_buffer(GST_APP_SRC(v->src), wrap(frame));
  }
}

WebRtcStats WebRtcSender::stats() const {
  WebRtcStats s;
  s.frames_in = impl_->frames_in;
  s.viewers_created = impl_->created;
  s.viewers_closed = impl_->closed;
  s.offers = impl_->shared->offers;
  s.answers = impl_->shared->answers;
  s.candidates_out = impl_->shared->candidates_out;
  s.candidates_in = impl_->shared->candidates_in;
  s.signals_ok = impl_->signals_ok;
  for (int i = 0; i < kSignalErrorCount; ++i) s.rejected[i] = impl_->rejected[i];
  for (const auto& v : impl_->snapshot()) {
    ViewerInfo info;
    info.id = v->id;
    info.overlay = v->overlay;
    info.offered = v->offered;
    info.connected = v->connected;
    info.frames = v->frames;
    info.bytes = v->bytes;
    info.keyframes = v->keyframes;
    info.keyframe_requests = v->requests;
    info.encoder_tid = v->encoder_tid;
    info.encoder_nice = v->encoder_nice;
    std::vector<double> ms;
    {
      std::lock_guard lock(v->timing);
      info.kbps = v->rate.kbps();
      ms.assign(v->encode_ms.begin(), v->encode_ms.end());
    }
    info.encode_ms_p50 = percentile(ms, 0.5);
    info.encode_ms_p95 = percentile(ms, 0.95);
    s.viewers.push_back(std::move(info));
  }
  return s;
}

}  // namespace kestrel::comm
