#pragma once
// The H.264 encode path every viewer's pipeline uses (comm/webrtc_sender.cpp), and the same
// path on its own (appsrc -> encoder -> appsink) for benchmarks and tests. GStreamer stays in
// the .cpp files (pimpl): this header is cheap to include.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace kestrel::comm {

struct EncoderSettings {
  int width = 640;
  int height = 480;
  int fps = 30;
  int kbps = 1500;
  int keyframe_interval_s = 2;  // a late packet loss heals by itself even without a PLI
};

// The default bitrate for a frame size: 3 Mbit/s at 1280x720 (the seed's figure), scaled by
// pixel count below it, never under 500 kbit/s.
int default_kbps(int width, int height);

// Initializes GStreamer once and checks the elements Kestrel's video needs; throws
// kestrel::Error naming the missing plugin (and scripts/setup) otherwise.
void init_gstreamer();

// gst-launch text of "raw I420 in -> constrained-baseline H.264 (avc, one access unit per
// buffer) out": x264 ultrafast + zerolatency on one thread (notes/webrtc-on-loopback.md: 0.8-1.5
// ms per 640x480 frame here, and it holds its bitrate where openh264 overshoots). The encoder is
// named "enc". Browsers reject High profile, hence the forced profile after the encoder.
std::string h264_encoder_launch(const EncoderSettings& s);

// appsrc ! <h264_encoder_launch> ! appsink, synchronous: encode() returns once the frame is out.
class H264Encoder {
 public:
  explicit H264Encoder(EncoderSettings settings);
  ~H264Encoder();
  H264Encoder(const H264Encoder&) = delete;
  H264Encoder& operator=(const H264Encoder&) = delete;

  struct Encoded {
    std::vector<std::uint8_t> bytes;  // avc: length-prefixed NAL units
    bool keyframe = false;
    double ms = 0.0;  // frame in -> encoded frame out
  };
  // i420: width*height*3/2 bytes. nullopt when the encoder produced nothing within a second.
  std::optional<Encoded> encode(const std::vector<std::uint8_t>& i420);
  void request_keyframe();
  void set_kbps(int kbps);
  std::string output_caps()
      const;  // e.g. "video/x-h264, ..., profile=(string)constrained-baseline"

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::comm
