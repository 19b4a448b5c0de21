#include "comm/clock_sync.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace kestrel::comm {

ClockSample clock_sample(const PongMsg& pong, Timestamp t3) {
  ClockSample s;
  s.rtt_ns = (t3 - pong.t0) - (pong.t2 - pong.t1);
  s.offset_ns = ((pong.t1 - pong.t0) + (pong.t2 - t3)) / 2;
  return s;
}

void ClockSync::add(const ClockSample& s) {
  samples_.push_back(s);
  if (samples_.size() > window_) samples_.pop_front();
}

std::int64_t ClockSync::offset_ns() const {
  if (samples_.empty()) return 0;
  return std::min_element(
             samples_.begin(), samples_.end(),
             [](const ClockSample& a, const ClockSample& b) { return a.rtt_ns < b.rtt_ns; })
      ->offset_ns;
}

std::int64_t ClockSync::rtt_percentile_ns(double q) const {
  if (samples_.empty()) return 0;
  std::vector<std::int64_t> r;
  for (const auto& s : samples_) r.push_back(s.rtt_ns);
  std::sort(r.begin(), r.end());
  const auto i = static_cast<std::size_t>(std::lround(std::clamp(q, 0.0, 1.0) * (r.size() - 1)));
  return r[i];
}

}  // namespace kestrel::comm
