#include "pipeline/imu_buffer.hpp"

#include <algorithm>

namespace kestrel::pipeline {

void ImuBuffer::add(const ImuSample& s) {
  if (!samples_.empty() && s.t <= samples_.back().t) {
    ++rejected_;
    return;
  }
  if (!s.gyro.allFinite() || !s.acc.allFinite()) {
    ++rejected_;
    return;
  }
  samples_.push_back(s);
}

bool ImuBuffer::at(Timestamp t, ImuSample* out) const {
  if (samples_.empty() || t < samples_.front().t || t > samples_.back().t) return false;
  auto it = std::lower_bound(samples_.begin(), samples_.end(), t,
                             [](const ImuSample& s, Timestamp v) { return s.t < v; });
  if (it->t == t) {
    *out = *it;
    return true;
  }
  *out = interpolate(*(it - 1), *it, t);
  return true;
}

std::vector<ImuSample> ImuBuffer::between(Timestamp t0, Timestamp t1) const {
  std::vector<ImuSample> out;
  ImuSample first, last;
  if (t1 <= t0 || !at(t0, &first) || !at(t1, &last)) return out;
  out.push_back(first);
  auto it = std::upper_bound(samples_.begin(), samples_.end(), t0,
                             [](Timestamp v, const ImuSample& s) { return v < s.t; });
  for (; it != samples_.end() && it->t < t1; ++it) out.push_back(*it);
  out.push_back(last);
  return out;
}

void ImuBuffer::drop_before(Timestamp t) {
  while (samples_.size() > 1 && samples_[1].t <= t) samples_.pop_front();
}

std::optional<SO3> gyro_delta(const ImuBuffer& imu, Timestamp t0, Timestamp t1,
                              const Vec3& gyro_bias) {
  const std::vector<ImuSample> s = imu.between(t0, t1);
  if (s.size() < 2) return std::nullopt;
  SO3 R;
  for (std::size_t i = 1; i < s.size(); ++i) {
    const double dt = static_cast<double>(s[i].t - s[i - 1].t) * 1e-9;
    R = R * SO3::exp((0.5 * (s[i].gyro + s[i - 1].gyro) - gyro_bias) * dt);
  }
  return R;
}

std::optional<Mat3> gyro_rotation(const ImuBuffer& imu, Timestamp t0, Timestamp t1,
                                  const SE3& T_body_camera) {
  const std::optional<SO3> R_prev_cur_body = gyro_delta(imu, t0, t1);
  if (!R_prev_cur_body) return std::nullopt;
  const Mat3 R_bc = T_body_camera.rotation();
  const Mat3 R_prev_cur_cam = R_bc.transpose() * R_prev_cur_body->matrix() * R_bc;
  return R_prev_cur_cam.transpose();
}

}  // namespace kestrel::pipeline
