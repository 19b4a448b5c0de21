#include "sim/spline_trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace kestrel::sim {
namespace {

double channel_of(const TrajectoryKnot& k, int c) {
  switch (c) {
    case 0:
      return k.position.x();
    case 1:
      return k.position.y();
    case 2:
      return k.position.z();
    case 3:
      return k.yaw;
    case 4:
      return k.pitch;
    default:
      return k.roll;
  }
}

}  // namespace

Mat3 rotation_from_euler(double yaw, double pitch, double roll) {
  return (Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
          Eigen::AngleAxisd(roll, Vec3::UnitX()))
      .toRotationMatrix();
}

SplineTrajectory::SplineTrajectory(std::vector<TrajectoryKnot> knots, double segment_time,
                                   Wobble wobble)
    : dt_(segment_time), wobble_(std::move(wobble)) {
  if (knots.empty()) throw std::invalid_argument("SplineTrajectory: no knots");
  if (!(segment_time > 0.0)) throw std::invalid_argument("SplineTrajectory: segment_time <= 0");
  // Yaw is unwrapped so that a knot at +179 deg followed by -179 deg turns by 2 deg, not 358.
  for (std::size_t i = 1; i < knots.size(); ++i) {
    while (knots[i].yaw - knots[i - 1].yaw > M_PI) knots[i].yaw -= 2.0 * M_PI;
    while (knots[i].yaw - knots[i - 1].yaw < -M_PI) knots[i].yaw += 2.0 * M_PI;
  }
  control_.push_back(knots.front());
  control_.push_back(knots.front());
  control_.insert(control_.end(), knots.begin(), knots.end());
  control_.push_back(knots.back());
  control_.push_back(knots.back());
}

double SplineTrajectory::duration() const { return static_cast<double>(control_.size() - 3) * dt_; }

void SplineTrajectory::channels(double t, double q[6], double dq[6], double ddq[6]) const {
  const int segments = static_cast<int>(control_.size()) - 3;
  double u = 0.0;
  int i = 0;
  bool held = false;
  if (t <= 0.0) {
    held = true;
  } else if (t >= duration()) {
    i = segments - 1;
    u = 1.0;
    held = true;
  } else {
    const double s = t / dt_;
    i = std::min(static_cast<int>(std::floor(s)), segments - 1);
    u = s - i;
  }
  // Uniform cubic B-spline basis and its derivatives with respect to u.
  const double u2 = u * u, u3 = u2 * u, m = 1.0 - u;
  const double B[4] = {m * m * m / 6.0, (3 * u3 - 6 * u2 + 4) / 6.0,
                       (-3 * u3 + 3 * u2 + 3 * u + 1) / 6.0, u3 / 6.0};
  const double dB[4] = {-m * m / 2.0, (3 * u2 - 4 * u) / 2.0, (-3 * u2 + 2 * u + 1) / 2.0,
                        u2 / 2.0};
  const double ddB[4] = {m, 3 * u - 2, -3 * u + 1, u};
  for (int c = 0; c < 6; ++c) {
    q[c] = dq[c] = ddq[c] = 0.0;
    for (int j = 0; j < 4; ++j) {
      const double v = channel_of(control_[i + j], c);
      q[c] += B[j] * v;
      if (!held) {
        dq[c] += dB[j] * v / dt_;
        ddq[c] += ddB[j] * v / (dt_ * dt_);
      }
    }
  }
  // The wobble's amplitude factor f(z) of the spline's height and its time derivatives.
  double f = 1.0, df = 0.0, ddf = 0.0;
  if (wobble_.fade_z_full > wobble_.fade_z_still) {
    const double span = wobble_.fade_z_full - wobble_.fade_z_still;
    const double x = (q[2] - wobble_.fade_z_still) / span;
    if (x <= 0.0) {
      f = 0.0;
    } else if (x < 1.0) {
      f = x * x * x * (x * (6.0 * x - 15.0) + 10.0);
      const double fz = 30.0 * x * x * (x - 1.0) * (x - 1.0) / span;
      const double fzz = 60.0 * x * (2.0 * x - 1.0) * (x - 1.0) / (span * span);
      df = fz * dq[2];
      ddf = fzz * dq[2] * dq[2] + fz * ddq[2];
    }
  }
  for (const auto& term : wobble_.terms) {
    const double w = 2.0 * M_PI * term.frequency_hz;
    const double arg = w * t + term.phase;
    const double s = term.amplitude * std::sin(arg);
    const double ds = term.amplitude * w * std::cos(arg);
    const double dds = -w * w * s;
    q[term.channel] += f * s;
    dq[term.channel] += df * s + f * ds;
    ddq[term.channel] += ddf * s + 2.0 * df * ds + f * dds;
  }
}

BodyState SplineTrajectory::state(double t) const {
  double q[6], dq[6], ddq[6];
  channels(t, q, dq, ddq);
  BodyState s;
  s.t = t;
  const double yaw = q[3], pitch = q[4], roll = q[5];
  const Mat3 Rz = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
  const Mat3 Rzy = Rz * Eigen::AngleAxisd(pitch, Vec3::UnitY()).toRotationMatrix();
  const Mat3 R = Rzy * Eigen::AngleAxisd(roll, Vec3::UnitX()).toRotationMatrix();
  s.T_w_b = SE3(SO3(R), Vec3(q[0], q[1], q[2]));
  s.v_w = Vec3(dq[0], dq[1], dq[2]);
  s.a_w = Vec3(ddq[0], ddq[1], ddq[2]);
  // Euler rates to the world angular velocity: each rate turns about its own (rotated) axis.
  const Vec3 omega_w =
      dq[3] * Vec3::UnitZ() + dq[4] * (Rz * Vec3::UnitY()) + dq[5] * (Rzy * Vec3::UnitX());
  s.omega_b = R.transpose() * omega_w;
  return s;
}

}  // namespace kestrel::sim
