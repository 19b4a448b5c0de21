#include "mapping/local_ba.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>
#include <unordered_map>

namespace kestrel::mapping {

bool reprojection_jacobians(const PinholeCamera& camera, const SE3& T_c_w, const Vec3& p_w,
                            const Vec2& uv, Vec2* r, Mat26* J_pose, Mat23* J_point) {
  const Vec3 p_c = T_c_w * p_w;
  if (!(p_c.z() > 1e-6)) return false;
  const double iz = 1.0 / p_c.z();
  *r = Vec2(camera.fx * p_c.x() * iz + camera.cx - uv.x(),
            camera.fy * p_c.y() * iz + camera.cy - uv.y());
  const Mat23 Jp = camera.project_jacobian(p_c);
  if (J_pose) {
    J_pose->leftCols<3>() = Jp;
    J_pose->rightCols<3>() = -Jp * SO3::hat(p_c);
  }
  if (J_point) *J_point = Jp * T_c_w.rotation();
  return true;
}

bool disparity_jacobians(double bf, const SE3& T_c_w, const Vec3& p_w, double measured, double* r,
                         Eigen::Matrix<double, 1, 6>* J_pose,
                         Eigen::Matrix<double, 1, 3>* J_point) {
  const Vec3 p_c = T_c_w * p_w;
  if (!(p_c.z() > 1e-6)) return false;
  *r = bf / p_c.z() - measured;
  const Eigen::RowVector3d Jd(0.0, 0.0, -bf / (p_c.z() * p_c.z()));
  if (J_pose) {
    J_pose->leftCols<3>() = Jd;
    J_pose->rightCols<3>() = -Jd * SO3::hat(p_c);
  }
  if (J_point) *J_point = Jd * T_c_w.rotation();
  return true;
}

void rotation_link_jacobians(const Mat3& R_to_from, const SE3& T_c_w_from, const SE3& T_c_w_to,
                             Vec3* r, Mat36* J_from, Mat36* J_to) {
  // E = D^T R_to R_from^T. A left perturbation Exp(phi) of R_to enters as Exp(D^T phi) E, one of
  // R_from as E Exp(-phi).
  const Mat3 D = R_to_from;
  const SO3 E(Mat3(D.transpose() * T_c_w_to.rotation() * T_c_w_from.rotation().transpose()));
  const Vec3 e = E.log();
  *r = e;
  if (J_to) {
    J_to->setZero();
    J_to->rightCols<3>() = SO3::left_jacobian_inverse(e) * D.transpose();
  }
  if (J_from) {
    J_from->setZero();
    J_from->rightCols<3>() = -SO3::right_jacobian_inverse(e);
  }
}

namespace {

// Poses live in Ceres as xi = log(T_c_w). Plus applies a left perturbation; the cost returns
// its Jacobian with respect to that perturbation and PlusJacobian is the identity, so Ceres'
// product J * PlusJacobian is exactly the tangent-space Jacobian (the usual "lifted" SE(3)
// trick that avoids differentiating log/exp).
class Se3LeftManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 6; }
  int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* out) const override {
    const Vec6 r =
        (SE3::exp(Eigen::Map<const Vec6>(delta)) * SE3::exp(Eigen::Map<const Vec6>(x))).log();
    Eigen::Map<Vec6>{out} = r;
    return true;
  }
  bool PlusJacobian(const double*, double* J) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(J).setIdentity();
    return true;
  }
  bool Minus(const double* y, const double* x, double* out) const override {
    Eigen::Map<Vec6>{out} =
        (SE3::exp(Eigen::Map<const Vec6>(y)) * SE3::exp(Eigen::Map<const Vec6>(x)).inverse()).log();
    return true;
  }
  bool MinusJacobian(const double*, double* J) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(J).setIdentity();
    return true;
  }
};

// The SE(3) of every pose block at the solver's current evaluation point. Each pose has dozens
// to thousands of observations, and exp() per residual was the largest single cost of local BA
// (13% of its thread on 150 s of market); Ceres calls PrepareForEvaluation with the user's
// blocks set to the point it is about to evaluate, so one exp per pose gives the same values.
class PoseCache final : public ceres::EvaluationCallback {
 public:
  explicit PoseCache(std::map<KeyframeId, Vec6>& poses) {
    for (auto& [k, xi] : poses) entries_.emplace(k, Entry{xi.data(), xi, SE3::exp(xi)});
  }
  // Recomputed for the poses whose blocks changed, whatever new_evaluation_point says: a new
  // problem (the second stage) starts with its own idea of what was evaluated last.
  void PrepareForEvaluation(bool, bool) override {
    for (auto& [k, e] : entries_) {
      const Eigen::Map<const Vec6> xi(e.xi);
      if (xi == e.at) continue;
      e.at = xi;
      e.T = SE3::exp(e.at);
    }
  }
  const SE3* of(KeyframeId k) const { return &entries_.at(k).T; }

 private:
  struct Entry {
    const double* xi;  // the solver's block
    Vec6 at;           // the value T was computed from
    SE3 T;
  };
  std::map<KeyframeId, Entry> entries_;
};

class ReprojectionCost final : public ceres::SizedCostFunction<2, 6, 3> {
 public:
  ReprojectionCost(const PinholeCamera& camera, const Vec2& uv, double sqrt_info, const SE3* T)
      : camera_(camera), uv_(uv), sqrt_info_(sqrt_info), T_(T) {}
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const SE3& T = *T_;
    const Vec3 p_w = Eigen::Map<const Vec3>(params[1]);
    Vec2 r;
    Mat26 Jpose;
    Mat23 Jpoint;
    if (!reprojection_jacobians(camera_, T, p_w, uv_, &r, &Jpose, &Jpoint)) {
      // Behind the camera: a large constant residual with zero slope keeps the solver away
      // without NaN; the outlier pass then drops the observation.
      residuals[0] = residuals[1] = 1e3;
      if (jacobians) {
        if (jacobians[0]) std::fill(jacobians[0], jacobians[0] + 12, 0.0);
        if (jacobians[1]) std::fill(jacobians[1], jacobians[1] + 6, 0.0);
      }
      return true;
    }
    Eigen::Map<Vec2>{residuals} = sqrt_info_ * r;
    if (jacobians) {
      if (jacobians[0]) {
        Eigen::Map<Eigen::Matrix<double, 2, 6, Eigen::RowMajor>>{jacobians[0]} = sqrt_info_ * Jpose;
      }
      if (jacobians[1]) {
        Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>>{jacobians[1]} =
            sqrt_info_ * Jpoint;
      }
    }
    return true;
  }

 private:
  PinholeCamera camera_;
  Vec2 uv_;
  double sqrt_info_;
  const SE3* T_;
};

class DisparityCost final : public ceres::SizedCostFunction<1, 6, 3> {
 public:
  DisparityCost(double bf, double measured, double sqrt_info, const SE3* T)
      : bf_(bf), measured_(measured), sqrt_info_(sqrt_info), T_(T) {}
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const SE3& T = *T_;
    const Vec3 p_w = Eigen::Map<const Vec3>(params[1]);
    double r = 0.0;
    Eigen::Matrix<double, 1, 6> Jpose;
    Eigen::Matrix<double, 1, 3> Jpoint;
    if (!disparity_jacobians(bf_, T, p_w, measured_, &r, &Jpose, &Jpoint)) {
      residuals[0] = 1e3;
      if (jacobians) {
        if (jacobians[0]) std::fill(jacobians[0], jacobians[0] + 6, 0.0);
        if (jacobians[1]) std::fill(jacobians[1], jacobians[1] + 3, 0.0);
      }
      return true;
    }
    residuals[0] = sqrt_info_ * r;
    if (jacobians) {
      if (jacobians[0]) Eigen::Map<Eigen::Matrix<double, 1, 6>>{jacobians[0]} = sqrt_info_ * Jpose;
      if (jacobians[1]) Eigen::Map<Eigen::Matrix<double, 1, 3>>{jacobians[1]} = sqrt_info_ * Jpoint;
    }
    return true;
  }

 private:
  double bf_, measured_, sqrt_info_;
  const SE3* T_;
};

// A point's views from the window's fixed keyframes, condensed: their costs depend on the point
// alone, so their robust Gauss-Newton model at the stage's start, 1/2 (p - p*)^T H (p - p*),
// stands in for them as one 3-D residual L^T (p - p*) with H = L L^T.
class PointPriorCost final : public ceres::SizedCostFunction<3, 3> {
 public:
  PointPriorCost(const Mat3& LT, const Vec3& target) : LT_(LT), target_(target) {}
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    Eigen::Map<Vec3>{residuals} = LT_ * (Eigen::Map<const Vec3>(params[0]) - target_);
    if (jacobians && jacobians[0]) {
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>{jacobians[0]} = LT_;
    }
    return true;
  }

 private:
  Mat3 LT_;
  Vec3 target_;
};

// Huber's weight rho'(s) at a squared residual s: what a view counts for in Gauss-Newton.
double huber_weight(double s, double delta) {
  return s <= delta * delta ? 1.0 : delta / std::sqrt(s);
}

// A gyro link between two keyframes' poses, whitened by its sigma.
class RotationLinkCost final : public ceres::SizedCostFunction<3, 6, 6> {
 public:
  RotationLinkCost(const Mat3& R_to_from, double sigma_rad) : D_(R_to_from), w_(1.0 / sigma_rad) {}
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const SE3 from = SE3::exp(Eigen::Map<const Vec6>(params[0]));
    const SE3 to = SE3::exp(Eigen::Map<const Vec6>(params[1]));
    Vec3 r;
    Mat36 Jf, Jt;
    rotation_link_jacobians(D_, from, to, &r, &Jf, &Jt);
    Eigen::Map<Vec3>{residuals} = w_ * r;
    if (jacobians) {
      using RowMajor36 = Eigen::Matrix<double, 3, 6, Eigen::RowMajor>;
      if (jacobians[0]) Eigen::Map<RowMajor36>{jacobians[0]} = w_ * Jf;
      if (jacobians[1]) Eigen::Map<RowMajor36>{jacobians[1]} = w_ * Jt;
    }
    return residuals[0] == residuals[0];
  }

 private:
  Mat3 D_;
  double w_;
};

}  // namespace

std::optional<LocalBaProblem> gather_local_ba(const Map& map, KeyframeId current,
                                              const LocalBaOptions& options) {
  if (!map.keyframe(current)) return std::nullopt;
  std::set<KeyframeId> local{current};
  for (KeyframeId k : map.covisible(current, options.window)) local.insert(k);
  std::set<PointId> points;
  for (KeyframeId k : local) {
    for (PointId p : map.keyframe(k)->point_of_feature) {
      if (p != kNoPoint && map.point(p)) points.insert(p);
    }
  }
  LocalBaProblem pb;
  pb.current = current;
  std::set<KeyframeId> fixed;
  // A revisited place's points are each seen by tens of keyframes, the same few hundred over
  // and over: each is looked up in the map (and sorted in or out of the window) once.
  std::unordered_map<KeyframeId, const Keyframe*> seen;
  const auto keyframe_of = [&](KeyframeId kid) {
    const auto [it, first_time] = seen.try_emplace(kid, nullptr);
    if (first_time) {
      it->second = map.keyframe(kid);
      if (it->second && !local.count(kid)) fixed.insert(kid);
    }
    return it->second;
  };
  // Sized once: on a place revisited for minutes the views number a hundred thousand, and
  // growing the array by doubling copied them over and over.
  std::size_t views = 0;
  for (PointId pid : points) views += map.point(pid)->observations.size();
  pb.observations.reserve(views);
  for (PointId pid : points) {
    const auto* mp = map.point(pid);
    pb.points.emplace_hint(pb.points.end(), pid, mp->p_w);
    for (const auto& [kid, feature] : mp->observations) {
      const Keyframe* kf = keyframe_of(kid);
      if (!kf) continue;
      const auto& f = kf->features;
      const auto fi = static_cast<std::size_t>(feature);
      const auto& kp = f.keypoints[fi];
      pb.observations.push_back({kid, pid, kp.un, 1.0 / f.level_scale(kp.level),
                                 f.level_sigma2(kp.level), f.has_depth(fi) ? f.depth[fi] : 0.0});
    }
  }
  // The first keyframe defines the world frame; without any anchor the gauge would be free.
  if (local.count(0)) {
    local.erase(0);
    fixed.insert(0);
  }
  if (fixed.empty()) {
    fixed.insert(*local.begin());
    local.erase(local.begin());
  }
  if (local.empty() || pb.observations.empty()) return std::nullopt;
  if (options.gyro_links) {
    // A link whose older end is outside the window holds that end still: it anchors the
    // window's rotation to the gyro.
    for (KeyframeId k : local) {
      const Keyframe* kf = map.keyframe(k);
      if (!kf->gyro || !(kf->gyro->sigma_rad > 0.0) || !map.keyframe(kf->gyro->from)) continue;
      const KeyframeId from = kf->gyro->from;
      if (!local.count(from)) fixed.insert(from);
      pb.rotation_links.push_back({from, k, kf->gyro->R_c_from, kf->gyro->sigma_rad});
    }
  }
  if (options.inertial) {
    for (KeyframeId k : local) {
      const Keyframe* kf = map.keyframe(k);
      if (!kf->gyro || !kf->gyro->imu || !kf->v_w) continue;
      const Keyframe* from = map.keyframe(kf->gyro->from);
      if (!from || !from->v_w || !(kf->gyro->imu->dt > 0.0) ||
          kf->gyro->imu->dt > options.inertial_max_dt_s) {
        continue;
      }
      if (!local.count(from->id)) fixed.insert(from->id);
      pb.inertial.push_back(
          {from->id, k, *kf->gyro->imu, kf->gyro->gravity, kf->gyro->T_body_camera});
      pb.v_w[k] = *kf->v_w;
      pb.v_w[from->id] = *from->v_w;
    }
  }
  for (KeyframeId k : local) pb.T_c_w[k] = map.keyframe(k)->T_c_w();
  for (KeyframeId k : fixed) pb.T_c_w[k] = map.keyframe(k)->T_c_w();
  pb.fixed = std::move(fixed);
  return pb;
}

LocalBaSolution solve_local_ba(const LocalBaProblem& pb, const PinholeCamera& camera,
                               const LocalBaOptions& options, const ExtraTerms& extra_terms) {
  LocalBaSolution sol;
  sol.current = pb.current;
  const auto& obs = pb.observations;
  std::map<KeyframeId, Vec6> poses;
  for (const auto& [k, T] : pb.T_c_w) poses[k] = T.log();
  std::map<PointId, Vec3> pts = pb.points;

  std::vector<std::uint8_t> active(obs.size(), 1);
  // The passes over every observation (RMS, outliers) take each keyframe's SE(3) from one exp
  // per keyframe: a revisited place has tens of thousands of views and a few hundred keyframes.
  std::vector<int> pose_index(obs.size());
  std::vector<KeyframeId> pose_ids;
  for (const auto& [k, xi] : poses) pose_ids.push_back(k);
  for (std::size_t i = 0; i < obs.size(); ++i) {
    pose_index[i] = static_cast<int>(std::lower_bound(pose_ids.begin(), pose_ids.end(), obs[i].kf) -
                                     pose_ids.begin());
  }
  const auto current_poses = [&]() {
    std::vector<SE3> T;
    T.reserve(poses.size());
    for (const auto& [k, xi] : poses) T.push_back(SE3::exp(xi));
    return T;
  };
  auto rms = [&]() {
    const std::vector<SE3> T = current_poses();
    double s = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      if (!active[i]) continue;
      Vec2 r;
      if (reprojection_jacobians(camera, T[static_cast<std::size_t>(pose_index[i])],
                                 pts[obs[i].point], obs[i].uv, &r, nullptr, nullptr)) {
        s += r.squaredNorm();
        ++n;
      }
    }
    return n ? std::sqrt(s / n) : 0.0;
  };
  sol.result.initial_rms_px = rms();

  // The observations' costs and the two robust losses are made once for both stages (one
  // allocation per residual and per loss, twice, was a tenth of the thread's time).
  PoseCache pose_cache(poses);
  ceres::HuberLoss reprojection_loss(std::sqrt(options.chi2_outlier));
  ceres::HuberLoss disparity_loss(std::sqrt(options.chi2_outlier_depth));
  std::vector<std::unique_ptr<ReprojectionCost>> reprojection_costs(obs.size());
  // The views from fixed keyframes are condensed per point (LocalBaOptions::condense_fixed_views).
  const bool condense = options.condense_fixed_views;
  std::vector<std::uint8_t> from_fixed(obs.size(), 0);
  if (condense) {
    for (std::size_t i = 0; i < obs.size(); ++i) from_fixed[i] = pb.fixed.count(obs[i].kf) ? 1 : 0;
  }
  std::vector<std::unique_ptr<DisparityCost>> disparity_costs(obs.size());
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (from_fixed[i]) continue;
    const auto& o = obs[i];
    const SE3* T = pose_cache.of(o.kf);
    reprojection_costs[i] = std::make_unique<ReprojectionCost>(camera, o.uv, o.sqrt_info, T);
    if (options.virtual_bf > 0.0 && o.depth > 0.0) {
      disparity_costs[i] = std::make_unique<DisparityCost>(
          options.virtual_bf, options.virtual_bf / o.depth, o.sqrt_info, T);
    }
  }

  ceres::HuberLoss link_loss(3.0);
  std::vector<std::unique_ptr<RotationLinkCost>> link_costs;
  for (const auto& l : pb.rotation_links) {
    link_costs.push_back(std::make_unique<RotationLinkCost>(l.R_to_from, l.sigma_rad));
  }

  const auto condensed_priors = [&]() {
    struct Normal {
      Mat3 H = Mat3::Zero();
      Vec3 g = Vec3::Zero();
    };
    std::map<PointId, Normal> normals;
    const double delta = std::sqrt(options.chi2_outlier);
    const double delta_depth = std::sqrt(options.chi2_outlier_depth);
    for (std::size_t i = 0; i < obs.size(); ++i) {
      if (!active[i] || !from_fixed[i]) continue;
      const auto& o = obs[i];
      const SE3& T = *pose_cache.of(o.kf);
      const Vec3& p = pts[o.point];
      Vec2 r = Vec2::Zero();
      Mat23 J = Mat23::Zero();
      if (!reprojection_jacobians(camera, T, p, o.uv, &r, nullptr, &J)) continue;
      Normal& n = normals[o.point];
      r *= o.sqrt_info;
      J *= o.sqrt_info;
      const double w = huber_weight(r.squaredNorm(), delta);
      n.H += w * J.transpose() * J;
      n.g += w * J.transpose() * r;
      if (options.virtual_bf > 0.0 && o.depth > 0.0) {
        double rd = 0.0;
        Eigen::Matrix<double, 1, 3> Jd = Eigen::Matrix<double, 1, 3>::Zero();
        disparity_jacobians(options.virtual_bf, T, p, options.virtual_bf / o.depth, &rd, nullptr,
                            &Jd);
        rd *= o.sqrt_info;
        Jd *= o.sqrt_info;
        const double wd = huber_weight(rd * rd, delta_depth);
        n.H += wd * Jd.transpose() * Jd;
        n.g += wd * Jd.transpose() * rd;
      }
    }
    std::vector<std::pair<PointId, std::unique_ptr<PointPriorCost>>> priors;
    priors.reserve(normals.size());
    for (const auto& [pid, n] : normals) {
      // One view without depth leaves a direction unseen; the tiny ridge keeps the model's
      // minimum where the view's own ray puts it along that direction.
      const Mat3 H = n.H + (1e-9 * n.H.trace() + 1e-12) * Mat3::Identity();
      const Eigen::LLT<Mat3> llt(H);
      if (llt.info() != Eigen::Success) continue;
      const Vec3 target = pts[pid] - llt.solve(n.g);
      if (!target.allFinite()) continue;
      priors.emplace_back(
          pid, std::make_unique<PointPriorCost>(Mat3(llt.matrixL()).transpose(), target));
    }
    return priors;
  };

  // Two stages as in ORB-SLAM: robust solve, drop outliers, solve again without them.
  for (int stage = 0; stage < 2; ++stage) {
    decltype(condensed_priors()) priors;
    if (condense) priors = condensed_priors();
    ceres::Problem::Options po;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.evaluation_callback = &pose_cache;
    ceres::Problem problem(po);
    Se3LeftManifold manifold;
    for (const auto& [pid, cost] : priors) {
      problem.AddResidualBlock(cost.get(), nullptr, pts[pid].data());
    }
    for (std::size_t i = 0; i < obs.size(); ++i) {
      if (!active[i] || from_fixed[i]) continue;
      const auto& o = obs[i];
      problem.AddResidualBlock(reprojection_costs[i].get(), &reprojection_loss, poses[o.kf].data(),
                               pts[o.point].data());
      if (disparity_costs[i]) {
        problem.AddResidualBlock(disparity_costs[i].get(), &disparity_loss, poses[o.kf].data(),
                                 pts[o.point].data());
      }
    }
    for (std::size_t i = 0; i < pb.rotation_links.size(); ++i) {
      const auto& l = pb.rotation_links[i];
      problem.AddResidualBlock(link_costs[i].get(), &link_loss, poses[l.from].data(),
                               poses[l.to].data());
    }
    if (extra_terms) extra_terms(problem, poses);
    for (auto& [k, xi] : poses) {
      if (!problem.HasParameterBlock(xi.data())) continue;
      problem.SetManifold(xi.data(), &manifold);
      if (pb.fixed.count(k)) problem.SetParameterBlockConstant(xi.data());
    }
    ceres::Solver::Options so;
    // Points are eliminated; what is left (the window's ~10 poses, velocities and biases) is a
    // small dense system, where the sparse path's ordering and symbolic analysis on every
    // solve cost more than they save (150 s of market: p50 17.9 -> 14.5 ms).
    so.linear_solver_type = ceres::DENSE_SCHUR;
    so.max_num_iterations = options.iterations;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    const std::vector<SE3> solved = current_poses();
    for (std::size_t i = 0; i < obs.size(); ++i) {
      if (!active[i]) continue;
      const auto& o = obs[i];
      const SE3& T = solved[static_cast<std::size_t>(pose_index[i])];
      Vec2 r;
      const bool front =
          reprojection_jacobians(camera, T, pts[o.point], o.uv, &r, nullptr, nullptr);
      double chi2 = r.squaredNorm();
      double threshold = options.chi2_outlier;
      if (front && options.virtual_bf > 0.0 && o.depth > 0.0) {
        double rd = 0.0;
        disparity_jacobians(options.virtual_bf, T, pts[o.point], options.virtual_bf / o.depth, &rd,
                            nullptr, nullptr);
        chi2 += rd * rd;
        threshold = options.chi2_outlier_depth;
      }
      if (!front || chi2 / o.level_sigma2 > threshold) active[i] = 0;
    }
  }
  sol.result.final_rms_px = rms();

  for (const auto& [k, xi] : poses) {
    if (pb.fixed.count(k)) continue;
    const SE3 T_c_w = SE3::exp(xi);
    if (T_c_w.is_finite()) sol.T_c_w[k] = T_c_w;
  }
  for (const auto& [p, x] : pts) {
    if (x.allFinite()) sol.points[p] = x;
  }
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (!active[i]) sol.outliers.emplace_back(obs[i].point, obs[i].kf);
  }
  sol.result.keyframes = static_cast<int>(pb.T_c_w.size() - pb.fixed.size());
  sol.result.fixed = static_cast<int>(pb.fixed.size());
  sol.result.points = static_cast<int>(pb.points.size());
  sol.result.observations = static_cast<int>(obs.size());
  sol.result.ran = true;
  return sol;
}

int apply_local_ba(Map& map, const LocalBaSolution& sol) {
  for (const auto& [k, T_c_w] : sol.T_c_w) {
    if (Keyframe* kf = map.keyframe(k)) kf->T_w_c = T_c_w.inverse();
  }
  for (const auto& [k, v] : sol.v_w) {
    if (Keyframe* kf = map.keyframe(k)) kf->v_w = v;
  }
  for (const auto& [p, x] : sol.points) {
    if (auto* mp = map.point(p)) mp->p_w = x;
  }
  int removed = 0;
  for (const auto& [p, k] : sol.outliers) {
    const auto* mp = map.point(p);
    if (!mp || !mp->observations.count(k)) continue;
    map.erase_observation(p, k);
    ++removed;
  }
  // BA moved the points; their observations changed only where erase_observation (above)
  // already refreshed them, so their descriptors stand.
  for (const auto& [p, x] : sol.points) {
    (void)x;
    map.update_point_geometry(p);
  }
  return removed;
}

LocalBaResult local_bundle_adjustment(Map& map, KeyframeId current, const PinholeCamera& camera,
                                      const LocalBaOptions& options) {
  const auto pb = gather_local_ba(map, current, options);
  if (!pb) return {};
  const LocalBaSolution sol = solve_local_ba(*pb, camera, options);
  LocalBaResult res = sol.result;
  res.outliers_removed = apply_local_ba(map, sol);
  return res;
}

}  // namespace kestrel::mapping
