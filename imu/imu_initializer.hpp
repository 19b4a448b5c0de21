#pragma once
// Inertial initialization, two ways:
//  (a) static: from a still period, gravity direction (roll, pitch of R_w_b, world z up), gyro
//      bias and a check of the accelerometer magnitude;
//  (b) visual-inertial: from keyframe poses of a visual-only map (metric, or up to scale for
//      monocular) and the pre-integrations between them: gyro bias, then a linear solve of
//      velocities, gravity (and scale), then a joint refinement with Ceres over gravity
//      direction, scale, velocities and both biases (ORB-SLAM3's inertial-only optimization;
//      Qin & Shen's linear alignment as its starting point).
// Neither throws on bad numerics: the status says what went wrong.
#include <span>
#include <vector>

#include "core/imu.hpp"
#include "core/se3.hpp"
#include "imu/nav_state.hpp"
#include "imu/preintegration.hpp"

namespace kestrel::imu {

// --- (a) static initialization ---

struct StaticInitOptions {
  double window_s = 1.0;     // stillness is judged on windows of this length
  double min_still_s = 2.0;  // the still period must last at least this long
  // Spread is measured on block means of this length, so that zero-mean rotor vibration of a
  // grounded multirotor (EuRoC: ~1 m/s^2 raw) does not hide stillness.
  double smoothing_s = 0.1;
  double max_gyro_std = 0.02;  // rad/s, norm of the per-axis standard deviations
  double max_acc_std = 0.2;    // m/s^2, same
  double gravity_magnitude = kGravityMagnitude;
  double gravity_tolerance = 0.4;  // m/s^2 allowed between |mean acc| and gravity
};

enum class StaticInitStatus { kOk, kTooFewSamples, kNotStill, kBadGravityMagnitude };
const char* to_string(StaticInitStatus status);

struct StaticInitResult {
  StaticInitStatus status = StaticInitStatus::kTooFewSamples;
  SO3 R_w_b;  // yaw set to zero
  Vec3 gyro_bias = Vec3::Zero();
  Vec3 acc_mean = Vec3::Zero();  // specific force in the body frame (≈ up, scaled by g)
  double acc_norm = 0.0;
  double gyro_std = 0.0;  // spread of block means over the still period
  double acc_std = 0.0;
  Timestamp still_begin = 0;
  Timestamp still_end = 0;
  std::size_t samples_used = 0;
  bool ok() const { return status == StaticInitStatus::kOk; }
};

// Uses the first still period of the (time-ordered) samples.
StaticInitResult static_initialize(std::span<const ImuSample> samples,
                                   const StaticInitOptions& options = {});

// R_w_b with zero yaw that maps the measured up direction (body frame) to world +z.
SO3 gravity_aligned_rotation(const Vec3& up_in_body);

// --- (b) visual-inertial initialization ---

struct ViInitOptions {
  bool estimate_scale = true;  // monocular: visual translations are up to scale
  double gravity_magnitude = kGravityMagnitude;
  int gyro_bias_iterations = 4;
  bool refine = true;  // Ceres refinement after the linear solution
  int max_refine_iterations = 50;
  double acc_bias_prior_sigma = 0.1;   // m/s^2, about the input accelerometer bias
  double gyro_bias_prior_sigma = 0.1;  // rad/s, about the linear gyro-bias estimate
  double max_gravity_error = 0.3;      // linear |g| may be off by this fraction
};

enum class ViInitStatus { kOk, kBadInput, kDegenerate, kBadGravity, kRefineFailed };
const char* to_string(ViInitStatus status);

struct ViInitResult {
  ViInitStatus status = ViInitStatus::kBadInput;
  SO3 R_w_v;           // visual frame → gravity-aligned world (zero yaw freedom)
  double scale = 1.0;  // metric = scale * visual
  ImuBias bias;
  std::vector<Vec3> velocities;        // body velocities in the world, one per keyframe
  Vec3 gravity_linear = Vec3::Zero();  // gravity in the visual frame from the linear step
  double scale_linear = 1.0;
  double gyro_residual_rms = 0.0;  // rad, rotation mismatch after the gyro-bias step
  int refine_iterations = 0;
  bool ok() const { return status == ViInitStatus::kOk; }

  // T_w_b of a keyframe from its visual camera pose.
  SE3 body_pose(const SE3& T_v_c, const SE3& T_b_c) const;
};

// T_v_c: keyframe camera poses in the visual frame, time-ordered. preintegrations[k] spans
// keyframes k → k+1 and is re-integrated in place with the estimated bias. T_b_c: the
// camera in the body (IMU) frame.
ViInitResult visual_inertial_initialize(std::span<const SE3> T_v_c, const SE3& T_b_c,
                                        std::span<Preintegration> preintegrations,
                                        const ViInitOptions& options = {});

}  // namespace kestrel::imu
