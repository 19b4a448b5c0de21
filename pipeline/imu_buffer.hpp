#pragma once
// Time synchronization of IMU with frames: samples are kept in stamp order and the interval
// between two frame stamps is returned with boundary samples interpolated to those exact
// stamps, so pre-integration covers precisely [t0, t1].
#include <deque>
#include <vector>

#include <optional>

#include "core/imu.hpp"
#include "core/se3.hpp"

namespace kestrel::pipeline {

class ImuBuffer {
 public:
  // Out-of-order or duplicate samples are ignored (counted), never reordered silently.
  void add(const ImuSample& s);
  // Samples covering [t0, t1]: first at exactly t0, last at exactly t1, interior samples
  // untouched. Empty when the buffer does not span both stamps.
  std::vector<ImuSample> between(Timestamp t0, Timestamp t1) const;
  // The interpolated sample at t; false when t is outside the buffered span.
  bool at(Timestamp t, ImuSample* out) const;
  // Forgets samples older than t (keeping one before t for interpolation).
  void drop_before(Timestamp t);

  bool empty() const { return samples_.empty(); }
  std::size_t size() const { return samples_.size(); }
  std::size_t rejected() const { return rejected_; }
  Timestamp latest() const { return samples_.empty() ? 0 : samples_.back().t; }
  Timestamp earliest() const { return samples_.empty() ? 0 : samples_.front().t; }

 private:
  std::deque<ImuSample> samples_;
  std::size_t rejected_ = 0;
};

// The body's rotation from t0 to t1 (R_b0_b1: directions at t1 into the body at t0) from the
// gyro less `gyro_bias`, midpoint rule. Nothing when the buffer does not span both stamps.
std::optional<SO3> gyro_delta(const ImuBuffer& imu, Timestamp t0, Timestamp t1,
                              const Vec3& gyro_bias = Vec3::Zero());

// Camera rotation between two frame stamps from the gyro (body frame), expressed in the camera
// frame: R_cur_prev maps directions of the previous camera into the current one (what the
// dynamic filter's ego-motion model takes). Nothing when the buffer does not span both.
std::optional<Mat3> gyro_rotation(const ImuBuffer& imu, Timestamp t0, Timestamp t1,
                                  const SE3& T_body_camera);

}  // namespace kestrel::pipeline
