#pragma once
// Round trip and clock offset between station and agent from ping/pong stamps (NTP):
//   rtt    = (t3 - t0) - (t2 - t1)
//   offset = ((t1 - t0) + (t2 - t3)) / 2      agent clock minus station clock
// The offset of the sample with the smallest round trip among the recent ones is reported:
// its error is bounded by half that round trip.
#include <cstdint>
#include <deque>

#include "comm/schema.hpp"

namespace kestrel::comm {

struct ClockSample {
  std::int64_t rtt_ns = 0;
  std::int64_t offset_ns = 0;
};

ClockSample clock_sample(const PongMsg& pong, Timestamp t3);

class ClockSync {
 public:
  explicit ClockSync(std::size_t window = 64) : window_(window) {}
  void add(const ClockSample& s);
  bool empty() const { return samples_.empty(); }
  std::int64_t offset_ns() const;                  // of the best (smallest-rtt) recent sample
  std::int64_t rtt_percentile_ns(double q) const;  // q in [0, 1] over the window
  std::size_t count() const { return samples_.size(); }

 private:
  std::size_t window_;
  std::deque<ClockSample> samples_;
};

}  // namespace kestrel::comm
