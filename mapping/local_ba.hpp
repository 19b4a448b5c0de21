#pragma once
// Local bundle adjustment (Ceres): the newest keyframe, its covisible keyframes and the points
// they see are optimized; other keyframes that see those points hold still and anchor the
// solution. Reprojection error with a Huber kernel, analytic Jacobians. Either synchronously
// (local_bundle_adjustment) or in three steps so that the solve can run on another thread:
// gather_local_ba copies what it needs out of the map (the map's owner), solve_local_ba works
// on that copy alone, apply_local_ba writes back what still exists (the map's owner again).
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <vector>

#include "core/camera.hpp"
#include "core/se3.hpp"
#include "mapping/map.hpp"

namespace ceres {
class Problem;
}

namespace kestrel::mapping {

using Mat26 = Eigen::Matrix<double, 2, 6>;
using Mat36 = Eigen::Matrix<double, 3, 6>;

struct LocalBaOptions {
  int window = 10;              // covisible keyframes optimized with the current one
  int iterations = 10;          // Levenberg-Marquardt steps per stage
  double chi2_outlier = 5.991;  // 2-dof observations above this (level-sigma units) are dropped
  double chi2_outlier_depth = 7.815;  // the same with the depth term (3 dof)
  // Depth enters as the disparity of a virtual stereo rig, bf / z in pixels, weighed like a
  // pixel of the keypoint's level (ORB-SLAM's RGB-D model). It pins the scale that reprojection
  // alone leaves free. A one-pixel disparity at bf = B is a depth sigma of z^2 / B, so B says
  // how much the sensor's depth is trusted: ORB-SLAM's TUM settings use 40 (sigma 0.025 z^2,
  // 22 cm at 3 m), an eighth of what a Kinect or a RealSense D455 reads, and the map then drifted
  // in scale: cafe draws with and without their walkers ended 0.4-1.1% too large or small, their
  // APE mostly that. 333 is sigma 0.003 z^2, the noise of the simulator's D455-like sensor and
  // about a Kinect v1's (TUM). A stereo rig's depth uses its own fx times baseline instead
  // (pipeline/system.cpp). 14 lock-step draws (cafe 1-4, market 1-4, uav-zigzag 1-4, ugv-loop
  // 1-2), APE summed: 40 -> 200 -> 333 with the same term in each frame's pose optimization,
  // 0.236 -> 0.179 -> 0.166 m; figures per draw in the README. corridor-dark 1-3 got worse,
  // 0.126 -> 0.205 m: on its grazing walls a keypoint's pixel error moves its depth more than
  // the sensor's noise does, which a per-feature depth sigma would have to say.
  double virtual_bf = 333.0;
  // Keyframes' gyro links (Keyframe::gyro) as rotation factors between them: off, the map is
  // vision's alone.
  bool gyro_links = true;
  // Keyframes' pre-integrations (GyroLink::imu) and velocities (Keyframe::v_w) are gathered as
  // inertial edges; imu::solve_inertial_local_ba turns them into factors (the visual-only
  // solve_local_ba leaves them out).
  bool inertial = false;
  double inertial_max_dt_s = 3.0;  // longer pre-integrations are left out
  // A point's views from fixed keyframes depend on the point alone: each stage replaces them by
  // their robust Gauss-Newton model at its start, one 3-D residual per point. The solve then
  // costs what the window's own views cost, however often the place was seen before.
  bool condense_fixed_views = true;
};

struct LocalBaResult {
  int keyframes = 0;  // optimized
  int fixed = 0;
  int points = 0;
  int observations = 0;
  int outliers_removed = 0;
  double initial_rms_px = 0.0;
  double final_rms_px = 0.0;
  bool ran = false;
};

// Residual project(T_c_w * p_w) - uv of the undistorted pinhole, and its Jacobians with respect
// to the left perturbation of T_c_w (delta = [rho; phi]) and to p_w. False behind the camera.
bool reprojection_jacobians(const PinholeCamera& camera, const SE3& T_c_w, const Vec3& p_w,
                            const Vec2& uv, Vec2* r, Mat26* J_pose, Mat23* J_point);

// Residual bf / z_c - measured disparity and its Jacobians (same conventions as above).
bool disparity_jacobians(double bf, const SE3& T_c_w, const Vec3& p_w, double measured, double* r,
                         Eigen::Matrix<double, 1, 6>* J_pose, Eigen::Matrix<double, 1, 3>* J_point);

// Residual Log(R_to_from^T R_c_w(to) R_c_w(from)^T) of a gyro link, and its Jacobians with
// respect to the left perturbations of the two poses (same conventions as above).
void rotation_link_jacobians(const Mat3& R_to_from, const SE3& T_c_w_from, const SE3& T_c_w_to,
                             Vec3* r, Mat36* J_from, Mat36* J_to);

// What one local BA needs, copied out of the map.
struct LocalBaProblem {
  KeyframeId current = -1;
  std::map<KeyframeId, SE3> T_c_w;  // optimized and fixed keyframes, at gather time
  std::set<KeyframeId> fixed;
  std::map<PointId, Vec3> points;
  struct Observation {
    KeyframeId kf;
    PointId point;
    Vec2 uv;              // undistorted keypoint
    double sqrt_info;     // 1 / level scale
    double level_sigma2;  // for the outlier test
    double depth;         // metres; 0 without
  };
  std::vector<Observation> observations;
  struct RotationLink {
    KeyframeId from, to;
    Mat3 R_to_from;  // the gyro's rotation of camera `from` into camera `to`
    double sigma_rad;
  };
  std::vector<RotationLink> rotation_links;  // at least one end optimized
  struct InertialEdge {
    KeyframeId from, to;
    PreintegratedImu imu;
    Vec3 gravity;
    SE3 T_body_camera;
  };
  std::vector<InertialEdge> inertial;  // at least one end optimized (LocalBaOptions::inertial)
  std::map<KeyframeId, Vec3> v_w;      // body velocities of the keyframes the edges join
};

struct LocalBaSolution {
  KeyframeId current = -1;
  std::map<KeyframeId, SE3> T_c_w;  // the optimized keyframes only
  std::map<PointId, Vec3> points;
  std::vector<std::pair<PointId, KeyframeId>> outliers;  // observations to drop
  std::map<KeyframeId, Vec3> v_w;                        // optimized keyframes' velocities
  LocalBaResult result;
};

// Nothing when the keyframe is gone or the window has nothing to optimize.
std::optional<LocalBaProblem> gather_local_ba(const Map& map, KeyframeId current,
                                              const LocalBaOptions& options = {});
// More residuals for each stage's problem (imu/'s inertial factors): `poses` holds every
// keyframe's block (log T_c_w, left-perturbed; fixed ones held constant by the solver). The
// problem owns neither cost nor loss functions: the caller keeps what it adds alive until
// solve_local_ba returns.
using ExtraTerms = std::function<void(ceres::Problem& problem, std::map<KeyframeId, Vec6>& poses)>;
LocalBaSolution solve_local_ba(const LocalBaProblem& problem, const PinholeCamera& camera,
                               const LocalBaOptions& options = {},
                               const ExtraTerms& extra_terms = {});
// Keyframes and points culled since the gather are skipped; returns the observations dropped.
int apply_local_ba(Map& map, const LocalBaSolution& solution);

LocalBaResult local_bundle_adjustment(Map& map, KeyframeId current, const PinholeCamera& camera,
                                      const LocalBaOptions& options = {});

}  // namespace kestrel::mapping
