#include "sim/live_source.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace kestrel::sim {

LiveSource::LiveSource(Scenario scenario, std::size_t recent_truth)
    : sim_(std::move(scenario)), recent_capacity_(std::max<std::size_t>(1, recent_truth)) {
  for (int k = 0; k < sim_.frame_count(); ++k) {
    const Simulator::FrameTiming ft = sim_.frame_timing(k);
    // As the recorder writes it: the truth at the true exposure time of every frame, dropped
    // ones included; the frame itself at the sensor's stamp.
    truth_.push_back(to_seconds(static_cast<Timestamp>(std::llround(ft.time * 1e9))),
                     sim_.trajectory().state(ft.time).T_w_b);
    if (ft.dropped) continue;
    frames_.push_back(k);
    stamps_.push_back(ft.stamp);
  }
  imu_ = sim_.imu();
}

std::optional<Measurement> LiveSource::next() {
  const bool frame_left = next_frame_ < frames_.size();
  const bool imu_left = next_imu_ < imu_.size();
  if (!frame_left && !imu_left) return std::nullopt;
  // On equal stamps the IMU sample comes first, as the sequence reader orders them.
  if (imu_left && (!frame_left || imu_[next_imu_].t <= stamps_[next_frame_])) {
    return Measurement{imu_[next_imu_++]};
  }
  SimFrame f = sim_.render(frames_[next_frame_]);
  RgbdFrame out;
  out.t = stamps_[next_frame_];
  out.color = std::move(f.color);
  out.depth = std::move(f.depth);
  out.depth_scale = sim_.calibration().depth_scale;
  out.source = "sim:" + sim_.scenario().name + " frame " + std::to_string(f.index);
  {
    std::lock_guard lock(recent_mutex_);
    recent_.push_back({out.t, std::move(f.mask)});
    if (recent_.size() > recent_capacity_) recent_.pop_front();
  }
  ++next_frame_;
  return Measurement{std::move(out)};
}

Image LiveSource::truth_mask(Timestamp t) const {
  std::lock_guard lock(recent_mutex_);
  for (const Recent& r : recent_) {
    if (r.stamp == t) return r.mask;
  }
  return Image{};
}

std::string LiveSource::describe() const {
  std::ostringstream os;
  os << "sim:" << sim_.scenario().name << " (live, RGB-D + IMU, " << frames_.size() << " frames, "
     << sim_.duration() << " s, ground truth)";
  return os.str();
}

}  // namespace kestrel::sim
