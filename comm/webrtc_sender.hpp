#pragma once
// Live H.264 video of one agent to any number of viewers over WebRTC (GStreamer webrtcbin with
// libnice), peer to peer; signaling goes through the caller (comm/webrtc_link.hpp carries it
// over MQTT). One pipeline per viewer:
//
//   appsrc (I420) ! x264enc (constrained baseline, zerolatency) ! rtph264pay ! webrtcbin
//
// so each viewer's bitrate follows its own link (comm/webrtc_bitrate.hpp), a PLI from one viewer
// costs the others nothing, and an overlay is drawn only for the viewers that asked for it.
// Encoding costs ~1-2 ms per 640x480 frame per viewer on this machine.
//
// Threads: push_frame() runs on the caller's thread and also creates and tears down viewers'
// pipelines, so pipelines only change when frames flow (an offer needs encoded frames anyway).
// handle() runs on the signaling thread. GStreamer runs its own threads inside comm/ (appsrc's
// streaming thread, webrtcbin's and libnice's): comm/ is the network layer, the one place
// besides pipeline/ that DESIGN.md lets own threads, and these never touch SLAM state — they
// only read the frames handed to push_frame(). GStreamer's headers stay in the .cpp (pimpl).
//
// Loopback (notes/webrtc-on-loopback.md): libnice ignores `lo`, so 127.0.0.1 is added to each
// viewer's NiceAgent by hand before PLAYING, which also confines ICE to it; ICE-TCP is off; the
// offer waits for the payloader's full caps (profile-level-id, sprop-parameter-sets).
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "comm/webrtc_frame.hpp"
#include "comm/webrtc_signaling.hpp"
#include "core/image.hpp"

namespace kestrel::comm {

struct VideoOptions {
  int width = 640;
  int height = 480;
  int fps = 30;  // the sensor rate the encoder budgets for
  int kbps = 0;  // target (and ceiling); 0: default_kbps(width, height)
  int min_kbps = 300;
  std::size_t max_viewers = 4;
  // A viewer that has not connected this long after its hello, or has sent nothing (no
  // `alive`) for this long, is dropped: a page that went away without a `bye` (reload, crash)
  // would otherwise keep an encoder busy, as libnice 0.1.21 never notices a silent peer.
  std::chrono::milliseconds connect_timeout{10000};
  std::chrono::milliseconds alive_timeout{8000};
  std::chrono::milliseconds rate_period{1000};  // bitrate update from the receiver reports
  // Telemetry wins over video: every GStreamer streaming thread of a viewer's pipeline (appsrc's,
  // which runs x264, and webrtcbin's send queues: payloading, SRTP, UDP) lowers its own nice
  // value to this as it starts, so under CPU shortage the kernel serves the tracking thread
  // that publishes poses and the MQTT network thread (nice 0) first, and video frames are late
  // instead (the leaky appsrc then drops the oldest). 0 leaves the threads at the caller's
  // priority. The environment variable KESTREL_VIDEO_NICE overrides it (A/B benchmarks).
  // Unprivileged processes cannot raise a thread's priority back, and GStreamer reuses its
  // threads, so this presumes that video is the only user of GStreamer in the process.
  int stream_nice = 10;
};

// "640x480", "1280x720" (or any even WxH up to 1920x1080); throws kestrel::Error naming `flag`.
void parse_video_size(const std::string& text, const std::string& flag, VideoOptions& options);

struct ViewerInfo {
  std::string id;
  bool overlay = false;
  bool offered = false;
  bool connected = false;
  int kbps = 0;
  std::uint64_t frames = 0;  // encoded
  std::uint64_t bytes = 0;
  std::uint64_t keyframes = 0;
  std::uint64_t keyframe_requests = 0;  // PLI / FIR from the browser and `keyframe` messages
  double encode_ms_p50 = 0.0;           // over the last 300 frames
  double encode_ms_p95 = 0.0;
  int encoder_tid = 0;   // the thread that ran the encoder (Linux tid), 0 before the first frame
  int encoder_nice = 0;  // its nice value as it ran the encoder (VideoOptions::stream_nice)
};

struct WebRtcStats {
  std::uint64_t frames_in = 0;
  std::uint64_t viewers_created = 0;
  std::uint64_t viewers_closed = 0;
  std::uint64_t offers = 0;
  std::uint64_t answers = 0;
  std::uint64_t candidates_out = 0;
  std::uint64_t candidates_in = 0;
  std::uint64_t signals_ok = 0;
  std::uint64_t rejected[kSignalErrorCount] = {};
  std::uint64_t rejected_total() const {
    std::uint64_t n = 0;
    for (auto r : rejected) n += r;
    return n;
  }
  std::vector<ViewerInfo> viewers;
};

class WebRtcSender {
 public:
  // Sends one signaling message (JSON text) to a viewer; called from GStreamer's threads and
  // from handle(), so it must be thread-safe and quick (MqttClient::publish is).
  using SendFn = std::function<void(const std::string& viewer, const std::string& json)>;

  // Throws kestrel::Error when GStreamer or a needed plugin is missing.
  WebRtcSender(VideoOptions options, SendFn send);
  ~WebRtcSender();
  WebRtcSender(const WebRtcSender&) = delete;
  WebRtcSender& operator=(const WebRtcSender&) = delete;

  // A signaling message from `viewer`. False when rejected (counted by reason, answered with
  // an error message when the viewer id is valid). Never throws.
  bool handle(const std::string& viewer, std::span<const std::uint8_t> payload);
  bool handle(const std::string& viewer, const std::string& text) {
    return handle(viewer, std::span<const std::uint8_t>(
                              reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
  }
  // Counts a rejection found before handle() (e.g. a malformed topic).
  void count_reject(SignalError e);

  // One camera frame, captured at `capture_wall_ns` (wall clock, the clock pings measure).
  // Cheap when nobody watches. The overlay, if any, is drawn for viewers that asked for it.
  void push_frame(const Image& image, std::int64_t capture_wall_ns,
                  const VideoOverlay* overlay = nullptr);

  WebRtcStats stats() const;
  const VideoOptions& options() const { return options_; }

 private:
  struct Impl;
  VideoOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::comm
