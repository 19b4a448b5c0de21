#pragma once
// Pose prediction from the IMU between visual fixes, for the tracker's prior and for dead
// reckoning through a lost track.
//
// Tracking gives a pose (a "fix") per frame but no velocity. Differencing two fixes one frame
// apart is useless (1 cm of pose noise over 33 ms is 30 cm/s), so the velocity comes from a
// least-squares fit over a window of fixes, with the accelerometer doing the rest: for every
// fix m after the window's first fix j,
//     p_m - p_j - ½ g τ² - R_j ΔP̂_jm  =  v_j τ + R_j (∂ΔP/∂b_a) δb_a,       τ = t_m - t_j,
// which is linear in the velocity at j and the accelerometer-bias change δb_a. Fitting both
// on every short window lets fix noise leak into the bias and back into the velocity, so the
// two are separated: the velocity comes from a short window with the biases held, and the
// biases from longer, non-overlapping windows (the gyro bias from ΔR̂_{m,m+1} Exp(J δb_g) =
// R_mᵀ R_{m+1}), each one a measurement with its own covariance for a Kalman update. The
// velocity at the newest fix then follows from pre-integration, and so does the pose at any
// later stamp the IMU covers.
#include <cmath>
#include <deque>
#include <optional>
#include <span>
#include <vector>

#include "core/imu.hpp"
#include "core/se3.hpp"
#include "imu/nav_state.hpp"

namespace kestrel::imu {

class Preintegration;

struct InertialPredictorOptions {
  ImuNoise noise;
  Vec3 gravity = gravity_vector();
  // Velocity: fit over the newest fixes of this span, biases held. Short, because a bias error
  // δ leaves about a third of δ·window in the velocity; long enough to average fix noise.
  double velocity_window_s = 0.5;
  double min_window_s = 0.2;  // with less history there is no prediction
  // Biases: every bias_window_s of new fixes gives one independent measurement of both biases
  // (a fit of velocity and accelerometer bias, and of the gyro bias from rotations), fused
  // into the running estimate by a Kalman update whose process noise is the bias random walk.
  double bias_window_s = 2.0;
  double initial_acc_bias_sigma = 0.1;    // m/s^2
  double initial_gyro_bias_sigma = 0.01;  // rad/s
  double fix_sigma = 0.01;                // metres: position noise of a visual fix
  double fix_rotation_sigma = 2e-3;       // radians: rotation noise of a visual fix
  double max_rotation_residual = 0.05;    // rad: a fix pair further off is not used for b_g
  // Floor (rad/s, one sigma per axis) of a window's gyro-bias measurement. The fit's own
  // covariance takes fix rotations as white noise; a tracked attitude's error is not white but
  // lasts seconds (the pose follows its map, and the gyro prior that already turns with the
  // bias estimate): half a degree of it over the window's 1 s pairs is 0.012 rad/s. Without
  // the floor, the first window of uav-zigzag draws whose take-off track carried a 2 degree
  // error set the bias to 0.011 rad/s (the simulated gyro's is below 2e-4), every later window
  // confirmed it through the prior, and the map tilted 15 degrees in 40 s (APE 1.79 m; 0.096
  // with the floor; the other draws that went wrong 1.01 -> 0.072 and 0.95 -> 0.150 m). Over
  // the twelve usual draws (whole scenes, lock-step; lost frames, APE m; cafe, market,
  // uav-zigzag on its old pad, corridor-dark, seeds 1-3) 0, 0.0069 / 0.0139 / 0.0045 -> 0, 0.0048 /
  // 0.0108 / 0.0039; 0, 0.091; 22, 0.051; 0, 0.045 -> 0, 0.052; 14, 0.048; 0, 0.057; 13, 0.053; 12,
  // 0.074; 19, 0.058 -> 12, 0.058; 14, 0.057; 19, 0.051; 17, 0.112; 10, 0.082; 45, 0.052 -> 9,
  // 0.077; 42, 0.101; 40, 0.080. The price: a true bias is learnt over tens of seconds instead of
  // one window; a still start gives it at once (pipeline::SystemOptions::static_gyro_bias).
  double gyro_bias_window_floor = 0.015;
  double max_gap_s = 2.0;  // dead reckoning longer than this is refused
  double buffer_s = 4.0;   // IMU history kept
};

struct InertialPrediction {
  SE3 T_w_b;
  Vec3 v_w = Vec3::Zero();   // body velocity in the world
  double since_fix_s = 0.0;  // how long the IMU alone carried the pose
};

class InertialPredictor {
 public:
  explicit InertialPredictor(const InertialPredictorOptions& options = {});

  // Time-ordered samples; anything not newer than the last one kept is ignored.
  void add_samples(std::span<const ImuSample> samples);
  // A visual pose of the body at t (t after the previous fix). Updates the velocity, and the
  // biases once a new bias window is full.
  void add_fix(Timestamp t, const SE3& T_w_b);
  // Forgets the fixes (after a relocalization jump, whose pose is not continuous with them);
  // biases are kept.
  void clear_fixes();
  // Forgets the fixes and starts again from a single one at t with a known velocity (the IMU's
  // own, carried through a loss): a relocalization corrects where the body is, not how fast it
  // moves, and predictions (and what relies on them) need not wait for a new velocity window.
  void reanchor(Timestamp t, const SE3& T_w_b, const Vec3& v_w);

  // Body pose at t from the newest fix and the IMU; nothing when the history is too short,
  // the IMU does not reach t, or the last fix is more than max_gap_s old.
  std::optional<InertialPrediction> predict(Timestamp t) const;

  // Attitude of the body at the newest sample, the newest fix's rotation carried on by the gyro
  // alone. Unlike predict() it has no time limit: over seconds the gyro drifts by hundredths of
  // a degree, enough to tell a look-alike place seen the other way round.
  struct Attitude {
    SO3 R_w_b;
    Timestamp t = 0;
    double since_fix_s = 0.0;
  };
  std::optional<Attitude> attitude() const;

  // World gravity, when the world is not the z-up one the options assume. The velocity is fitted
  // again: one fitted under the assumed gravity is off by the difference times the window's
  // length (EuRoC, camera-first world: 4 m/s for a body at rest).
  void set_gravity(const Vec3& g);
  const Vec3& gravity() const { return options_.gravity; }

  const ImuBias& bias() const { return bias_; }
  // A gyro bias measured apart from vision (the gyro's mean over a still period), with its one
  // sigma per axis: the estimate and its covariance restart from it.
  void set_gyro_bias(const Vec3& b, double sigma);
  // Whether the gyro bias has been measured at all (set_gyro_bias, or a window fused): until
  // then it is the initial guess, zero with initial_gyro_bias_sigma.
  bool gyro_bias_measured() const { return gyro_bias_measured_; }
  // One sigma of the gyro bias estimate (rad/s, the largest axis).
  double gyro_bias_sigma() const { return std::sqrt(gyro_bias_cov_.diagonal().maxCoeff()); }
  std::size_t fixes() const { return fixes_.size(); }
  // Velocity at the newest fix, once the window is long enough.
  const std::optional<Vec3>& velocity() const { return v_last_; }
  // The stamp of the fix the velocity was last fitted at; reanchor() carries a velocity on
  // without a fit, and one carried from reanchor to reanchor through a flaky track, never
  // checked against vision again, drifts without bound.
  const std::optional<Timestamp>& velocity_fitted_at() const { return velocity_fitted_at_; }

 private:
  struct Fix {
    Timestamp t;
    SE3 T_w_b;
  };
  std::vector<ImuSample> samples_between(Timestamp t0, Timestamp t1) const;
  // For every fix m from `first` on, against fix j = first with the IMU between them:
  // y_m = p_m - p_j - ½ g τ² - R_j ΔP̂_jm (τ = t_m - t_j) and ∂ΔP_jm/∂b_a. `pre_out` gets the
  // pre-integration from j to the newest fix.
  struct WindowTerm {
    double tau;
    Vec3 y;
    Mat3 dp_dba;
  };
  std::vector<WindowTerm> window_terms(std::size_t first, const std::vector<ImuSample>& samples,
                                       Preintegration* pre_out) const;
  bool update_biases();  // false: no update (too few fixes, no IMU, a failed solve)
  void update_velocity();

  InertialPredictorOptions options_;
  std::deque<ImuSample> imu_;
  std::deque<Fix> fixes_;
  ImuBias bias_;
  Mat3 acc_bias_cov_;
  Mat3 gyro_bias_cov_;
  bool gyro_bias_measured_ = false;
  Timestamp bias_updated_at_ = 0;  // stamp of the newest fix the biases have seen
  std::optional<Vec3> v_last_;
  std::optional<Timestamp> velocity_fitted_at_;
  Fix v_fix_{0, SE3()};  // the fix v_last_ belongs to
  // Gyro-propagated attitude (attitude()); nothing before the first fix.
  std::optional<SO3> att_R_;
  Timestamp att_t_ = 0;
  Timestamp att_fix_t_ = 0;
};

}  // namespace kestrel::imu
