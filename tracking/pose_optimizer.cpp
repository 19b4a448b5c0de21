#include "tracking/pose_optimizer.hpp"

#include <Eigen/Cholesky>
#include <cmath>

#include "mapping/local_ba.hpp"

namespace kestrel::tracking {

PoseOptimizerResult optimize_pose(const PinholeCamera& camera,
                                  const std::vector<PoseObservation>& obs, const SE3& T_c_w_initial,
                                  const PoseOptimizerOptions& options, const PosePrior* prior) {
  PoseOptimizerResult res;
  res.T_c_w = T_c_w_initial;
  res.inlier.assign(obs.size(), 1);
  SE3 T = T_c_w_initial;
  // The residual of one observation (reprojection, then the disparity when it has depth), its
  // Jacobian and its outlier threshold; false behind the camera.
  const auto residual = [&](const PoseObservation& o, Eigen::Vector3d* r,
                            Eigen::Matrix<double, 3, 6>* J, double* chi2_max) {
    Vec2 r2;
    Mat26 J2;
    if (!pose_residual(camera, T, o.p_w, o.uv, &r2, J ? &J2 : nullptr)) return false;
    r->head<2>() = r2;
    if (J) J->topRows<2>() = J2;
    (*r)(2) = 0.0;
    if (J) J->row(2).setZero();
    *chi2_max = options.chi2_outlier;
    if (options.virtual_bf > 0.0 && o.depth > 0.0) {
      double rd = 0.0;
      Eigen::Matrix<double, 1, 6> Jd;
      if (!mapping::disparity_jacobians(options.virtual_bf, T, o.p_w, options.virtual_bf / o.depth,
                                        &rd, J ? &Jd : nullptr, nullptr)) {
        return false;
      }
      (*r)(2) = rd;
      if (J) J->row(2) = Jd;
      *chi2_max = options.chi2_outlier_depth;
    }
    return true;
  };
  for (int round = 0; round < options.rounds; ++round) {
    // The robust kernel helps while outliers are still mixed in; the last round, with the
    // outliers set aside, is plain least squares (as ORB-SLAM does).
    const bool robust = round < options.rounds - 1;
    for (int it = 0; it < options.iterations; ++it) {
      Mat6 H = Mat6::Zero();
      Vec6 b = Vec6::Zero();
      int used = 0;
      for (std::size_t i = 0; i < obs.size(); ++i) {
        if (!res.inlier[i]) continue;
        Eigen::Vector3d r;
        Eigen::Matrix<double, 3, 6> J;
        double chi2_max = 0.0;
        if (!residual(obs[i], &r, &J, &chi2_max)) continue;
        const double chi2 = r.squaredNorm() * obs[i].inv_sigma2;
        double w = obs[i].inv_sigma2;
        if (robust && chi2 > chi2_max) w *= std::sqrt(chi2_max / chi2);
        H.noalias() += w * J.transpose() * J;
        b.noalias() += w * J.transpose() * r;
        ++used;
      }
      if (prior) {
        // d log(exp(δ) T T_p⁻¹) / dδ is the identity to first order near the prior.
        const Vec6 e = (T * prior->T_c_w.inverse()).log();
        if (e.allFinite()) {
          H.noalias() += prior->information;
          b.noalias() += prior->information * e;
        }
      }
      if (used < 3) break;
      const Vec6 delta = H.ldlt().solve(-b);
      if (!delta.allFinite()) break;
      T = SE3::exp(delta) * T;
      if (delta.squaredNorm() < 1e-16) break;
    }
    // Classify every observation against the current pose; earlier outliers may come back.
    res.inliers = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      Eigen::Vector3d r;
      double chi2_max = 0.0;
      const bool front = residual(obs[i], &r, nullptr, &chi2_max);
      const bool in = front && r.squaredNorm() * obs[i].inv_sigma2 <= chi2_max;
      res.inlier[i] = in ? 1 : 0;
      res.inliers += in ? 1 : 0;
    }
    if (res.inliers < options.min_inliers) break;
  }
  res.ok = T.is_finite() && res.inliers >= options.min_inliers;
  if (res.ok) res.T_c_w = T;
  return res;
}

}  // namespace kestrel::tracking
