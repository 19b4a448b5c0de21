#include "tracking/pose_optimizer.hpp"

#include <Eigen/Cholesky>
#include <cmath>

namespace kestrel::tracking {

PoseOptimizerResult optimize_pose(const PinholeCamera& camera,
                                  const std::vector<PoseObservation>& obs, const SE3& T_c_w_initial,
                                  const PoseOptimizerOptions& options, const PosePrior* prior) {
  PoseOptimizerResult res;
  res.T_c_w = T_c_w_initial;
  res.inlier.assign(obs.size(), 1);
  const double huber = std::sqrt(options.chi2_outlier);
  SE3 T = T_c_w_initial;
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
        Vec2 r;
        Mat26 J;
        if (!pose_residual(camera, T, obs[i].p_w, obs[i].uv, &r, &J)) continue;
        const double chi2 = r.squaredNorm() * obs[i].inv_sigma2;
        double w = obs[i].inv_sigma2;
        if (robust && chi2 > huber * huber) w *= huber / std::sqrt(chi2);
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
      Vec2 r;
      const bool front = pose_residual(camera, T, obs[i].p_w, obs[i].uv, &r);
      const bool in = front && r.squaredNorm() * obs[i].inv_sigma2 <= options.chi2_outlier;
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
