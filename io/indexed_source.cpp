#include "io/indexed_source.hpp"

#include <algorithm>
#include <stdexcept>

namespace kestrel::io {

void IndexedSource::set_streams(std::vector<Timestamp> frame_stamps, std::vector<ImuSample> imu) {
  if (!std::is_sorted(frame_stamps.begin(), frame_stamps.end())) {
    throw std::logic_error("IndexedSource: frame stamps not sorted");
  }
  if (!std::is_sorted(imu.begin(), imu.end(),
                      [](const ImuSample& a, const ImuSample& b) { return a.t < b.t; })) {
    throw std::logic_error("IndexedSource: IMU stamps not sorted");
  }
  frame_stamps_ = std::move(frame_stamps);
  imu_ = std::move(imu);
  rewind();
}

std::optional<Measurement> IndexedSource::next() {
  const bool have_frame = next_frame_ < frame_stamps_.size();
  const bool have_imu = next_imu_ < imu_.size();
  if (!have_frame && !have_imu) return std::nullopt;
  if (have_imu && (!have_frame || imu_[next_imu_].t <= frame_stamps_[next_frame_])) {
    return Measurement(imu_[next_imu_++]);
  }
  // Advance only after a successful load, so a caller that catches the error sees it again.
  Measurement m = load_frame(next_frame_);
  ++next_frame_;
  return m;
}

std::optional<std::pair<Timestamp, Timestamp>> IndexedSource::time_span() const {
  if (frame_stamps_.empty() && imu_.empty()) return std::nullopt;
  Timestamp lo = 0, hi = 0;
  bool first = true;
  auto add = [&](Timestamp t) {
    if (first || t < lo) lo = t;
    if (first || t > hi) hi = t;
    first = false;
  };
  if (!frame_stamps_.empty()) {
    add(frame_stamps_.front());
    add(frame_stamps_.back());
  }
  if (!imu_.empty()) {
    add(imu_.front().t);
    add(imu_.back().t);
  }
  return std::make_pair(lo, hi);
}

}  // namespace kestrel::io
