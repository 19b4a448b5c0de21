#pragma once
// Loss- and delay-driven bitrate for one viewer, from the receiver reports the browser sends
// back (RTCP RR: fraction lost, round trip). webrtcbin 1.22 has no congestion controller of
// its own (rtpgccbwe lives in gst-plugins-rs, not in Debian 12), so this is the loss half of
// Google Congestion Control (draft-ietf-rmcat-gcc-02 section 6) plus a back-off when the round
// trip grows well past the best one seen: queues are building somewhere on the path.
#include <algorithm>

namespace kestrel::comm {

class BitrateController {
 public:
  BitrateController(int target_kbps, int min_kbps)
      : target_(target_kbps), min_(std::min(min_kbps, target_kbps)), kbps_(target_kbps) {}

  // One receiver report: fraction of packets lost since the last one (0..1), round trip in
  // seconds (< 0: unknown). Returns the new bitrate.
  int update(double fraction_lost, double rtt_s) {
    if (rtt_s >= 0) min_rtt_ = min_rtt_ < 0 ? rtt_s : std::min(min_rtt_, rtt_s);
    double k = kbps_;
    if (fraction_lost > 0.10) {
      k *= 1.0 - 0.5 * fraction_lost;
    } else if (rtt_s >= 0 && min_rtt_ >= 0 && rtt_s > 2.0 * min_rtt_ + 0.1) {
      k *= 0.85;
    } else if (fraction_lost < 0.02) {
      k *= 1.08;
    }
    kbps_ = std::clamp(static_cast<int>(k), min_, target_);
    return kbps_;
  }
  int kbps() const { return kbps_; }
  int target() const { return target_; }

 private:
  int target_;
  int min_;
  int kbps_;
  double min_rtt_ = -1.0;
};

}  // namespace kestrel::comm
