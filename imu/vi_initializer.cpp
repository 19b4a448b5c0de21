// Visual-inertial initialization (imu_initializer.hpp, part b).
#include <ceres/autodiff_cost_function.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>
#include <ceres/solver.h>

#include <Eigen/Dense>
#include <cmath>
#include <memory>

#include "imu/imu_factor.hpp"
#include "imu/imu_initializer.hpp"

namespace kestrel::imu {
namespace {

using MatX = Eigen::MatrixXd;
using VecX = Eigen::VectorXd;

// Keyframe geometry in the visual frame: body rotation, camera position (up to scale) and the
// lever arm from camera to body, so that p_v_b = s * cam + lever.
struct KeyframeGeometry {
  Mat3 R_v_b;
  Vec3 cam;
  Vec3 lever;
};

std::vector<KeyframeGeometry> body_geometry(std::span<const SE3> T_v_c, const SE3& T_b_c) {
  const SE3 T_c_b = T_b_c.inverse();
  std::vector<KeyframeGeometry> out;
  out.reserve(T_v_c.size());
  for (const SE3& T : T_v_c) {
    out.push_back(
        {T.rotation() * T_c_b.rotation(), T.translation(), T.rotation() * T_c_b.translation()});
  }
  return out;
}

// Solves Σ_k ‖J_R_bg,k δ − Log(ΔR_kᵀ R_iᵀ R_j)‖² for the gyro bias, re-integrating between
// iterations so that each step is linearized at the current bias. Returns the final RMS
// rotation mismatch.
double solve_gyro_bias(const std::vector<KeyframeGeometry>& kf, std::span<Preintegration> pre,
                       int iterations, ImuBias& bias) {
  double rms = 0.0;
  for (int it = 0; it < iterations; ++it) {
    Mat3 H = Mat3::Zero();
    Vec3 b = Vec3::Zero();
    double sq = 0.0;
    for (std::size_t k = 0; k < pre.size(); ++k) {
      const SO3 R_ij(Mat3(kf[k].R_v_b.transpose() * kf[k + 1].R_v_b));
      const Vec3 e = (pre[k].delta_R().inverse() * R_ij).log();
      const Mat3& J = pre[k].dR_dbg();
      H += J.transpose() * J;
      b += J.transpose() * e;
      sq += e.squaredNorm();
    }
    rms = std::sqrt(sq / static_cast<double>(pre.size()));
    const Vec3 delta = H.ldlt().solve(b);
    if (!delta.allFinite()) return -1.0;
    bias.gyro += delta;
    for (Preintegration& p : pre) p.reintegrate(bias);
    if (delta.norm() < 1e-9) break;
  }
  return rms;
}

// Linear alignment: unknowns [v_0 … v_{N-1}, g_v, (s)] from the velocity and position
// equations of every pre-integration, in the visual frame.
bool solve_linear(const std::vector<KeyframeGeometry>& kf, std::span<const Preintegration> pre,
                  bool estimate_scale, std::vector<Vec3>& v, Vec3& g, double& s) {
  const int n = static_cast<int>(kf.size());
  const int cols = 3 * n + 3 + (estimate_scale ? 1 : 0);
  const int g_col = 3 * n;
  MatX A = MatX::Zero(6 * (n - 1), cols);
  VecX b = VecX::Zero(6 * (n - 1));
  for (int k = 0; k + 1 < n; ++k) {
    const Preintegration& p = pre[k];
    const double dt = p.dt();
    const Mat3& Ri = kf[k].R_v_b;
    const int r = 6 * k;
    const Vec3 dcam = kf[k + 1].cam - kf[k].cam;
    // s Δcam + Δlever − v_i dt − ½ g dt² = R_i Δp
    A.block<3, 3>(r, 3 * k) = -dt * Mat3::Identity();
    A.block<3, 3>(r, g_col) = -0.5 * dt * dt * Mat3::Identity();
    b.segment<3>(r) = Ri * p.delta_p() - (kf[k + 1].lever - kf[k].lever);
    if (estimate_scale) {
      A.block<3, 1>(r, cols - 1) = dcam;
    } else {
      b.segment<3>(r) -= dcam;
    }
    // v_j − v_i − g dt = R_i Δv
    A.block<3, 3>(r + 3, 3 * k) = -Mat3::Identity();
    A.block<3, 3>(r + 3, 3 * (k + 1)) = Mat3::Identity();
    A.block<3, 3>(r + 3, g_col) = -dt * Mat3::Identity();
    b.segment<3>(r + 3) = Ri * p.delta_v();
  }
  // Column scaling keeps the velocity, gravity and scale unknowns comparably conditioned.
  VecX col_scale = A.colwise().norm().transpose();
  for (int c = 0; c < cols; ++c) col_scale(c) = col_scale(c) > 0.0 ? 1.0 / col_scale(c) : 1.0;
  const Eigen::ColPivHouseholderQR<MatX> qr(A * col_scale.asDiagonal());
  if (qr.rank() < cols) return false;
  const VecX x = col_scale.asDiagonal() * qr.solve(b);
  if (!x.allFinite()) return false;
  v.resize(n);
  for (int k = 0; k < n; ++k) v[k] = x.segment<3>(3 * k);
  g = x.segment<3>(g_col);
  s = estimate_scale ? x(cols - 1) : 1.0;
  return true;
}

// Pre-integration residual in the visual frame with gravity direction and scale unknown
// (ORB-SLAM3's inertial-only edge): tilt = 2-DoF correction of R_w_v about world x and y,
// log_scale, v_i, v_j (visual frame, metric), bg, ba.
struct AlignmentCost {
  Mat3 Ri, Rj;
  Vec3 dcam, dlever;
  Vec3 g_world;
  Mat3 R0_T;  // initial R_w_v transposed
  SO3 dR;
  Vec3 dv, dp;
  double dt;
  ImuBias b0;
  Mat3 J_R_bg, J_v_bg, J_v_ba, J_p_bg, J_p_ba;
  Mat9 sqrt_info;

  template <typename T>
  bool operator()(const T* tilt, const T* log_scale, const T* vi_, const T* vj_, const T* bg_,
                  const T* ba_, T* out) const {
    using V3 = Eigen::Matrix<T, 3, 1>;
    using M3 = Eigen::Matrix<T, 3, 3>;
    const Eigen::Map<const V3> vi(vi_), vj(vj_), bg(bg_), ba(ba_);
    const T neg_tilt[3] = {-tilt[0], -tilt[1], T(0)};
    const T gw[3] = {T(g_world.x()), T(g_world.y()), T(g_world.z())};
    T g_tilted[3];
    ceres::AngleAxisRotatePoint(neg_tilt, gw, g_tilted);
    const V3 g = R0_T.cast<T>() * Eigen::Map<const V3>(g_tilted);
    using std::exp;
    const T s = exp(log_scale[0]);

    const V3 dbg = bg - b0.gyro.cast<T>();
    const V3 dba = ba - b0.acc.cast<T>();
    const V3 phi = J_R_bg.cast<T>() * dbg;
    M3 E;  // Exp(J δbg), column-major as ceres expects
    ceres::AngleAxisToRotationMatrix(phi.data(), E.data());
    const M3 err = (dR.matrix().cast<T>() * E).transpose() * (Ri.transpose() * Rj).cast<T>();
    V3 rR;
    ceres::RotationMatrixToAngleAxis(err.data(), rR.data());

    const M3 RiT = Ri.transpose().cast<T>();
    const V3 rv = RiT * (vj - vi - g * T(dt)) -
                  (dv.cast<T>() + J_v_bg.cast<T>() * dbg + J_v_ba.cast<T>() * dba);
    const V3 rp =
        RiT * (s * dcam.cast<T>() + dlever.cast<T>() - vi * T(dt) - T(0.5 * dt * dt) * g) -
        (dp.cast<T>() + J_p_bg.cast<T>() * dbg + J_p_ba.cast<T>() * dba);
    Eigen::Matrix<T, 9, 1> r;
    r << rR, rv, rp;
    Eigen::Map<Eigen::Matrix<T, 9, 1>>{out} = sqrt_info.cast<T>() * r;
    return true;
  }
};

}  // namespace

const char* to_string(ViInitStatus status) {
  switch (status) {
    case ViInitStatus::kOk:
      return "ok";
    case ViInitStatus::kBadInput:
      return "bad input";
    case ViInitStatus::kDegenerate:
      return "degenerate motion";
    case ViInitStatus::kBadGravity:
      return "gravity magnitude not recovered";
    case ViInitStatus::kRefineFailed:
      return "refinement failed";
  }
  return "unknown";
}

SE3 ViInitResult::body_pose(const SE3& T_v_c, const SE3& T_b_c) const {
  const SE3 T_c_b = T_b_c.inverse();
  const SO3 R_v_b = T_v_c.so3() * T_c_b.so3();
  const Vec3 p_v_b = scale * T_v_c.translation() + T_v_c.so3() * T_c_b.translation();
  return SE3(R_w_v * R_v_b, R_w_v * p_v_b);
}

ViInitResult visual_inertial_initialize(std::span<const SE3> T_v_c, const SE3& T_b_c,
                                        std::span<Preintegration> pre,
                                        const ViInitOptions& options) {
  ViInitResult result;
  const std::size_t n = T_v_c.size();
  if (n < 4 || pre.size() + 1 != n) return result;
  for (const SE3& T : T_v_c) {
    if (!T.is_finite()) return result;
  }
  for (const Preintegration& p : pre) {
    if (!(p.dt() > 0.0)) return result;
  }
  const std::vector<KeyframeGeometry> kf = body_geometry(T_v_c, T_b_c);

  ImuBias bias = pre[0].bias();
  result.gyro_residual_rms =
      solve_gyro_bias(kf, pre, std::max(1, options.gyro_bias_iterations), bias);
  result.bias = bias;
  if (result.gyro_residual_rms < 0.0) {
    result.status = ViInitStatus::kDegenerate;
    return result;
  }

  std::vector<Vec3> v;
  Vec3 g_v;
  double s = 1.0;
  if (!solve_linear(kf, pre, options.estimate_scale, v, g_v, s) || !(s > 0.0)) {
    result.status = ViInitStatus::kDegenerate;
    return result;
  }
  result.gravity_linear = g_v;
  result.scale_linear = s;
  const double g_norm = g_v.norm();
  if (!(std::abs(g_norm - options.gravity_magnitude) <=
        options.max_gravity_error * options.gravity_magnitude)) {
    result.status = ViInitStatus::kBadGravity;
    return result;
  }
  // The yaw of R_w_v is free; the shortest rotation taking g_v to world down is one choice.
  const SO3 R0(Mat3(Quat::FromTwoVectors(g_v, Vec3(0.0, 0.0, -1.0)).toRotationMatrix()));
  result.R_w_v = R0;
  result.scale = s;

  if (options.refine) {
    double tilt[2] = {0.0, 0.0};
    double log_scale = std::log(s);
    double bg[3], ba[3];
    Eigen::Map<Vec3>{bg} = bias.gyro;
    Eigen::Map<Vec3>{ba} = bias.acc;
    std::vector<Vec3> vel = v;
    ceres::Problem problem;
    for (std::size_t k = 0; k + 1 < n; ++k) {
      const Preintegration& p = pre[k];
      auto* cost = new AlignmentCost{kf[k].R_v_b,
                                     kf[k + 1].R_v_b,
                                     kf[k + 1].cam - kf[k].cam,
                                     kf[k + 1].lever - kf[k].lever,
                                     Vec3(0.0, 0.0, -options.gravity_magnitude),
                                     R0.matrix().transpose(),
                                     p.delta_R(),
                                     p.delta_v(),
                                     p.delta_p(),
                                     p.dt(),
                                     p.bias(),
                                     p.dR_dbg(),
                                     p.dv_dbg(),
                                     p.dv_dba(),
                                     p.dp_dbg(),
                                     p.dp_dba(),
                                     sqrt_information(p.covariance())};
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<AlignmentCost, 9, 2, 1, 3, 3, 3, 3>(cost), nullptr, tilt,
          &log_scale, vel[k].data(), vel[k + 1].data(), bg, ba);
    }
    problem.AddResidualBlock(new Vec3PriorFactor(bias.acc, options.acc_bias_prior_sigma), nullptr,
                             ba);
    problem.AddResidualBlock(new Vec3PriorFactor(bias.gyro, options.gyro_bias_prior_sigma), nullptr,
                             bg);
    if (!options.estimate_scale) problem.SetParameterBlockConstant(&log_scale);

    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.max_num_iterations = options.max_refine_iterations;
    solver.num_threads = 1;
    solver.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    result.refine_iterations = static_cast<int>(summary.iterations.size());
    const bool finite = std::isfinite(tilt[0]) && std::isfinite(tilt[1]) &&
                        std::isfinite(log_scale) && Eigen::Map<Vec3>(bg).allFinite() &&
                        Eigen::Map<Vec3>(ba).allFinite();
    if (!summary.IsSolutionUsable() || !finite) {
      result.status = ViInitStatus::kRefineFailed;
      return result;
    }
    result.R_w_v = SO3::exp(Vec3(tilt[0], tilt[1], 0.0)) * R0;
    result.scale = std::exp(log_scale);
    bias.gyro = Eigen::Map<Vec3>(bg);
    bias.acc = Eigen::Map<Vec3>(ba);
    v = vel;
    for (Preintegration& p : pre) p.reintegrate(bias);
  }

  result.bias = bias;
  result.velocities.resize(n);
  for (std::size_t k = 0; k < n; ++k) result.velocities[k] = result.R_w_v * v[k];
  result.status = ViInitStatus::kOk;
  return result;
}

}  // namespace kestrel::imu
