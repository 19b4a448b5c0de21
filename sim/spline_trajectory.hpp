#pragma once
// A smooth (C2) body trajectory with analytic derivatives, so that the simulated IMU is exact:
// a uniform cubic B-spline over position and Z-Y-X Euler angles, plus an optional sum of
// sinusoids (the hand-held wobble). Every quantity the IMU needs (velocity, acceleration, body
// angular rate) is differentiated in closed form, never by finite differences.
#include <vector>

#include "core/se3.hpp"

namespace kestrel::sim {

// One control point: position [m] and yaw (about world z), pitch (about the yawed y), roll [rad].
struct TrajectoryKnot {
  Vec3 position = Vec3::Zero();
  double yaw = 0.0;
  double pitch = 0.0;
  double roll = 0.0;
};

// Sinusoidal perturbation added to the spline: each of the six channels (x y z yaw pitch roll)
// is a sum of a few sines with fixed amplitude, frequency and phase.
struct Wobble {
  struct Term {
    int channel = 0;  // 0..2 position xyz, 3..5 yaw pitch roll
    double amplitude = 0.0;
    double frequency_hz = 0.0;
    double phase = 0.0;
  };
  std::vector<Term> terms;
  // fade_z_full > fade_z_still: the wobble is nothing while the spline's own height (before the
  // wobble) is at most fade_z_still and full from fade_z_full up, smootherstep between (C2, so
  // the IMU's accelerations stay continuous). A drone sits still on its pad; gusts and the
  // hover controller's error come once it is airborne. Equal (the default): always full.
  double fade_z_still = 0.0;
  double fade_z_full = 0.0;
};

struct BodyState {
  double t = 0.0;
  SE3 T_w_b;
  Vec3 v_w = Vec3::Zero();      // velocity in the world
  Vec3 a_w = Vec3::Zero();      // acceleration in the world (no gravity)
  Vec3 omega_b = Vec3::Zero();  // angular rate in the body frame
};

class SplineTrajectory {
 public:
  // The first and last knots are repeated three times internally so that the body starts and
  // ends at rest exactly on them. segment_time: seconds between knots (> 0).
  SplineTrajectory(std::vector<TrajectoryKnot> knots, double segment_time, Wobble wobble = {});

  // Seconds covered by the spline; state() holds the end pose after it.
  double duration() const;
  BodyState state(double t) const;

 private:
  // 6-vector channel values (x y z yaw pitch roll) and their first two time derivatives.
  void channels(double t, double q[6], double dq[6], double ddq[6]) const;

  std::vector<TrajectoryKnot> control_;
  double dt_;
  Wobble wobble_;
};

// R_w_b from Z-Y-X Euler angles: Rz(yaw) Ry(pitch) Rx(roll).
Mat3 rotation_from_euler(double yaw, double pitch, double roll);

}  // namespace kestrel::sim
