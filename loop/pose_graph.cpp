#include "loop/pose_graph.hpp"

#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <array>
#include <memory>

#include "imu/pose_manifold.hpp"

namespace kestrel::loop {
namespace {

// Residual of one relative-pose edge on blocks [t q] (imu/pose_manifold.hpp layout):
// the translation error in the `from` frame's measured orientation and twice the vector part
// of the rotation error quaternion, each divided by its sigma.
class RelativePoseCost {
 public:
  RelativePoseCost(const SE3& T_ij, double sigma_t, double sigma_r)
      : t_ij_(T_ij.translation()),
        q_ij_(T_ij.quaternion()),
        inv_sigma_t_(1.0 / sigma_t),
        inv_sigma_r_(1.0 / sigma_r) {}

  template <typename T>
  bool operator()(const T* pose_i, const T* pose_j, T* residual) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    using QuatT = Eigen::Quaternion<T>;
    const Eigen::Map<const Vec3T> t_i(pose_i);
    const Eigen::Map<const QuatT> q_i(pose_i + 3);
    const Eigen::Map<const Vec3T> t_j(pose_j);
    const Eigen::Map<const QuatT> q_j(pose_j + 3);
    const QuatT q_i_inv = q_i.conjugate();
    const Vec3T t_ij_est = q_i_inv * (t_j - t_i);
    const QuatT q_ij_est = q_i_inv * q_j;
    const QuatT dq = q_ij_.template cast<T>().conjugate() * q_ij_est;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r.template head<3>() =
        T(inv_sigma_t_) * (q_ij_.template cast<T>().conjugate() * (t_ij_est - t_ij_.cast<T>()));
    // Both signs of dq are the same rotation; take the one near the identity.
    const T sign = dq.w() < T(0) ? T(-1) : T(1);
    r.template tail<3>() = T(2.0 * inv_sigma_r_) * sign * dq.vec();
    return true;
  }

 private:
  Vec3 t_ij_;
  Quat q_ij_;
  double inv_sigma_t_;
  double inv_sigma_r_;
};

}  // namespace

PoseGraphResult optimize_pose_graph(const std::map<PoseId, SE3>& poses,
                                    const std::vector<PoseGraphEdge>& edges,
                                    const std::set<PoseId>& fixed,
                                    const PoseGraphOptions& options) {
  PoseGraphResult result;
  result.poses = poses;
  if (poses.empty()) return result;

  std::map<PoseId, std::array<double, imu::kPoseParamSize>> params;
  for (const auto& [id, T] : poses) imu::pose_to_params(T, params[id].data());

  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  imu::PoseManifold manifold;
  int used_edges = 0;
  for (const PoseGraphEdge& e : edges) {
    const auto a = params.find(e.from);
    const auto b = params.find(e.to);
    if (a == params.end() || b == params.end() || e.from == e.to) continue;
    auto* cost = new ceres::AutoDiffCostFunction<RelativePoseCost, 6, 7, 7>(new RelativePoseCost(
        e.T_from_to, e.sigma_translation > 0.0 ? e.sigma_translation : options.sigma_translation,
        e.sigma_rotation > 0.0 ? e.sigma_rotation : options.sigma_rotation));
    ceres::LossFunction* loss = nullptr;
    if (e.kind == EdgeKind::kLoop && options.loop_loss_scale > 0.0)
      loss = new ceres::CauchyLoss(options.loop_loss_scale);
    problem.AddResidualBlock(cost, loss, a->second.data(), b->second.data());
    ++used_edges;
  }
  if (used_edges == 0) return result;
  for (auto& [id, p] : params) {
    if (!problem.HasParameterBlock(p.data())) continue;
    problem.SetManifold(p.data(), &manifold);
  }
  bool any_fixed = false;
  for (PoseId id : fixed) {
    const auto it = params.find(id);
    if (it != params.end() && problem.HasParameterBlock(it->second.data())) {
      problem.SetParameterBlockConstant(it->second.data());
      any_fixed = true;
    }
  }
  if (!any_fixed) {
    for (auto& [id, p] : params) {
      if (problem.HasParameterBlock(p.data())) {
        problem.SetParameterBlockConstant(p.data());
        break;
      }
    }
  }

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);

  result.converged = summary.IsSolutionUsable() && summary.termination_type == ceres::CONVERGENCE;
  result.iterations = static_cast<int>(summary.iterations.size());
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  if (!summary.IsSolutionUsable()) return result;
  for (const auto& [id, p] : params) {
    SE3 T = imu::params_to_pose(p.data());
    if (!T.translation().allFinite()) return result;  // keep the input poses
    result.poses[id] = T;
  }
  return result;
}

}  // namespace kestrel::loop
