#include "core/imu.hpp"

namespace kestrel {

ImuSample interpolate(const ImuSample& a, const ImuSample& b, Timestamp t) {
  if (b.t == a.t) return a;
  const double s = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
  ImuSample out;
  out.t = t;
  out.gyro = (1.0 - s) * a.gyro + s * b.gyro;
  out.acc = (1.0 - s) * a.acc + s * b.acc;
  return out;
}

}  // namespace kestrel
