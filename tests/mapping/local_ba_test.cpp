#include "mapping/local_ba.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

namespace kestrel::mapping {
namespace {

PinholeCamera camera() {
  PinholeCamera c;
  c.fx = 525.0;
  c.fy = 525.0;
  c.cx = 319.5;
  c.cy = 239.5;
  return c;
}

// What a keyframe at T_c_w sees of `truth`: every point projected with pixel noise, its depth
// with relative noise, all static.
FrameFeatures observe(const PinholeCamera& cam, const SE3& T_c_w, const std::vector<Vec3>& truth,
                      std::normal_distribution<double>& px_noise,
                      std::normal_distribution<double>& n01, double depth_rel_sigma,
                      std::mt19937& rng) {
  FrameFeatures f;
  f.width = cam.width;
  f.height = cam.height;
  for (const Vec3& p : truth) {
    const Vec3 p_c = T_c_w * p;
    tracking::Keypoint kp;
    kp.un = kp.px = *cam.project(p_c) + Vec2(px_noise(rng), px_noise(rng));
    f.keypoints.push_back(kp);
    f.descriptors.emplace_back();
    f.depth.push_back(p_c.z() * (1.0 + depth_rel_sigma * n01(rng)));
    f.points_c.push_back(p_c);
    f.status.push_back(tracking::FeatureStatus::kStatic);
  }
  return f;
}

TEST(LocalBa, ReprojectionJacobiansMatchNumeric) {
  const PinholeCamera cam = camera();
  const SE3 T(SO3::exp(Vec3(0.3, -0.2, 0.1)), Vec3(0.2, 0.4, -0.3));
  const Vec3 p_w = T.inverse() * Vec3(0.4, -0.3, 2.2);
  const Vec2 uv(310.0, 250.0);
  Vec2 r;
  Mat26 Jpose;
  Mat23 Jpoint;
  ASSERT_TRUE(reprojection_jacobians(cam, T, p_w, uv, &r, &Jpose, &Jpoint));
  constexpr double h = 1e-6;
  for (int j = 0; j < 6; ++j) {
    Vec6 d = Vec6::Zero();
    d[j] = h;
    Vec2 rp, rm;
    reprojection_jacobians(cam, SE3::exp(d) * T, p_w, uv, &rp, nullptr, nullptr);
    reprojection_jacobians(cam, SE3::exp(-d) * T, p_w, uv, &rm, nullptr, nullptr);
    EXPECT_LT(((rp - rm) / (2 * h) - Jpose.col(j)).norm(), 1e-4) << "pose column " << j;
  }
  for (int j = 0; j < 3; ++j) {
    Vec3 d = Vec3::Zero();
    d[j] = h;
    Vec2 rp, rm;
    reprojection_jacobians(cam, T, p_w + d, uv, &rp, nullptr, nullptr);
    reprojection_jacobians(cam, T, p_w - d, uv, &rm, nullptr, nullptr);
    EXPECT_LT(((rp - rm) / (2 * h) - Jpoint.col(j)).norm(), 1e-4) << "point column " << j;
  }
}

TEST(LocalBa, DisparityJacobiansMatchNumeric) {
  const SE3 T(SO3::exp(Vec3(-0.1, 0.25, 0.3)), Vec3(0.5, -0.1, 0.2));
  const Vec3 p_w = T.inverse() * Vec3(-0.3, 0.2, 1.7);
  double r = 0.0;
  Eigen::Matrix<double, 1, 6> Jpose;
  Eigen::Matrix<double, 1, 3> Jpoint;
  ASSERT_TRUE(disparity_jacobians(40.0, T, p_w, 20.0, &r, &Jpose, &Jpoint));
  constexpr double h = 1e-6;
  for (int j = 0; j < 6; ++j) {
    Vec6 d = Vec6::Zero();
    d[j] = h;
    double rp = 0, rm = 0;
    disparity_jacobians(40.0, SE3::exp(d) * T, p_w, 20.0, &rp, nullptr, nullptr);
    disparity_jacobians(40.0, SE3::exp(-d) * T, p_w, 20.0, &rm, nullptr, nullptr);
    EXPECT_NEAR((rp - rm) / (2 * h), Jpose(j), 1e-5) << "pose column " << j;
  }
  for (int j = 0; j < 3; ++j) {
    Vec3 d = Vec3::Zero();
    d[j] = h;
    double rp = 0, rm = 0;
    disparity_jacobians(40.0, T, p_w + d, 20.0, &rp, nullptr, nullptr);
    disparity_jacobians(40.0, T, p_w - d, 20.0, &rm, nullptr, nullptr);
    EXPECT_NEAR((rp - rm) / (2 * h), Jpoint(j), 1e-5) << "point column " << j;
  }
}

// Six keyframes along a sideways path look at 300 points; keyframe 0 is exact (it defines the
// world), the others and every point start perturbed.
TEST(LocalBa, RotationLinkJacobiansMatchNumeric) {
  const SE3 Ti(SO3::exp(Vec3(0.3, -0.2, 0.1)), Vec3(0.2, 0.4, -0.3));
  const SE3 Tj(SO3::exp(Vec3(0.25, -0.1, 0.3)), Vec3(0.1, 0.5, -0.2));
  // A gyro rotation close to, not equal to, the poses' relative rotation.
  const Mat3 D = (SO3::exp(Vec3(0.01, -0.02, 0.015)) * Tj.so3() * Ti.so3().inverse()).matrix();
  Vec3 r;
  Mat36 Ji, Jj;
  rotation_link_jacobians(D, Ti, Tj, &r, &Ji, &Jj);
  EXPECT_GT(r.norm(), 0.01);
  constexpr double h = 1e-6;
  for (int j = 0; j < 6; ++j) {
    Vec6 d = Vec6::Zero();
    d[j] = h;
    Vec3 rp, rm;
    rotation_link_jacobians(D, SE3::exp(d) * Ti, Tj, &rp, nullptr, nullptr);
    rotation_link_jacobians(D, SE3::exp(-d) * Ti, Tj, &rm, nullptr, nullptr);
    EXPECT_LT(((rp - rm) / (2 * h) - Ji.col(j)).norm(), 1e-6) << "from column " << j;
    rotation_link_jacobians(D, Ti, SE3::exp(d) * Tj, &rp, nullptr, nullptr);
    rotation_link_jacobians(D, Ti, SE3::exp(-d) * Tj, &rm, nullptr, nullptr);
    EXPECT_LT(((rp - rm) / (2 * h) - Jj.col(j)).norm(), 1e-6) << "to column " << j;
  }
  // Consistent poses: no residual.
  rotation_link_jacobians((Tj.so3() * Ti.so3().inverse()).matrix(), Ti, Tj, &r, nullptr, nullptr);
  EXPECT_LT(r.norm(), 1e-12);
}

TEST(LocalBa, RecoversPosesAndPointsFromNoisyInitialValues) {
  const PinholeCamera cam = camera();
  std::mt19937 rng(42);
  std::normal_distribution<double> px_noise(0.0, 0.5), n01(0.0, 1.0);
  std::uniform_real_distribution<double> ux(-2.0, 2.0), uy(-1.5, 1.5), uz(2.0, 5.0);
  const int kPoints = 300, kKeyframes = 6;
  std::vector<Vec3> truth;
  for (int i = 0; i < kPoints; ++i) truth.emplace_back(ux(rng), uy(rng), uz(rng));
  std::vector<SE3> poses;
  for (int k = 0; k < kKeyframes; ++k) {
    poses.emplace_back(SO3::exp(Vec3(0.01 * k, -0.03 * k, 0.005 * k)),
                       Vec3(0.25 * k, 0.04 * k, 0.05 * k));
  }
  Map map;
  std::vector<PointId> ids;
  for (int k = 0; k < kKeyframes; ++k) {
    const FrameFeatures f = observe(cam, poses[static_cast<std::size_t>(k)].inverse(), truth,
                                    px_noise, n01, 0.002, rng);
    SE3 init = poses[static_cast<std::size_t>(k)];
    if (k > 0) {
      Vec6 d;
      for (int j = 0; j < 3; ++j) d[j] = 0.02 * n01(rng);
      for (int j = 3; j < 6; ++j) d[j] = 0.01 * n01(rng);
      init = SE3::exp(d) * init;
    }
    const KeyframeId kid = map.add_keyframe(k, init, f);
    for (int i = 0; i < kPoints; ++i) {
      if (k == 0) {
        const Vec3 noisy =
            truth[static_cast<std::size_t>(i)] + 0.03 * Vec3(n01(rng), n01(rng), n01(rng));
        ids.push_back(map.add_point(noisy, kid, i));
      } else {
        map.add_observation(ids[static_cast<std::size_t>(i)], kid, i);
      }
    }
  }
  for (int k = 0; k < kKeyframes; ++k) map.update_connections(k);

  auto pose_error = [&]() {
    double worst = 0.0;
    for (int k = 0; k < kKeyframes; ++k) {
      worst = std::max(worst, (map.keyframe(k)->T_w_c.translation() -
                               poses[static_cast<std::size_t>(k)].translation())
                                  .norm());
    }
    return worst;
  };
  auto point_rms = [&]() {
    double s = 0.0;
    for (int i = 0; i < kPoints; ++i) {
      s += (map.point(ids[static_cast<std::size_t>(i)])->p_w - truth[static_cast<std::size_t>(i)])
               .squaredNorm();
    }
    return std::sqrt(s / kPoints);
  };
  const double pose_before = pose_error(), points_before = point_rms();
  const LocalBaResult r = local_bundle_adjustment(map, kKeyframes - 1, cam);
  ASSERT_TRUE(r.ran);
  EXPECT_EQ(r.keyframes, kKeyframes - 1);
  EXPECT_EQ(r.fixed, 1);
  EXPECT_EQ(r.points, kPoints);
  EXPECT_LT(r.outliers_removed, kPoints * kKeyframes / 50);
  EXPECT_LT(r.final_rms_px, 0.8);
  EXPECT_GT(r.initial_rms_px, 5.0);
  EXPECT_GT(pose_before, 0.02);
  EXPECT_LT(pose_error(), 2e-3) << "before " << pose_before;
  // Along the ray, a point 5 m away seen over a 1.25 m baseline with 0.5 px noise is known to
  // about 1-2 cm (z^2 sigma / (f b)); the RMS over all points sits near 1.3 cm.
  EXPECT_LT(point_rms(), 1.6e-2) << "before " << points_before;
  for (int k = 1; k < kKeyframes; ++k) {
    const double deg =
        (map.keyframe(k)->T_w_c.so3().inverse() * poses[static_cast<std::size_t>(k)].so3())
            .angle() *
        180 / M_PI;
    EXPECT_LT(deg, 0.05) << "keyframe " << k;
  }
}

TEST(LocalBa, GyroLinksHoldKeyframeRotationsWhereVisionIsWeak) {
  // Few, noisy points far away: vision leaves each keyframe's rotation off by a few tenths of a
  // degree. The gyro's relative rotations (exact here) tie the keyframes to the fixed first one.
  const PinholeCamera cam = camera();
  std::mt19937 rng(7);
  std::normal_distribution<double> px_noise(0.0, 2.0), n01(0.0, 1.0);
  std::uniform_real_distribution<double> ux(-3.0, 3.0), uy(-2.0, 2.0), uz(6.0, 8.0);
  const int kPoints = 40, kKeyframes = 5;
  std::vector<Vec3> truth;
  for (int i = 0; i < kPoints; ++i) truth.emplace_back(ux(rng), uy(rng), uz(rng));
  std::vector<SE3> poses;
  for (int k = 0; k < kKeyframes; ++k) {
    poses.emplace_back(SO3::exp(Vec3(0.02 * k, -0.05 * k, 0.01 * k)),
                       Vec3(0.1 * k, 0.02 * k, 0.03 * k));
  }
  auto build = [&](bool links) {
    Map map;
    std::mt19937 r2(11);
    std::vector<PointId> ids;
    for (int k = 0; k < kKeyframes; ++k) {
      const FrameFeatures f = observe(cam, poses[static_cast<std::size_t>(k)].inverse(), truth,
                                      px_noise, n01, 0.02, r2);
      SE3 init = poses[static_cast<std::size_t>(k)];
      if (k > 0) init = SE3::exp(Vec6(0.02, -0.01, 0.01, 0.01, -0.01, 0.008)) * init;
      const KeyframeId kid = map.add_keyframe(k, init, f);
      if (links && k > 0) {
        GyroLink l;
        l.from = kid - 1;
        l.R_c_from = (poses[static_cast<std::size_t>(k)].so3().inverse() *
                      poses[static_cast<std::size_t>(k - 1)].so3())
                         .matrix();
        l.sigma_rad = 1e-4;
        map.keyframe(kid)->gyro = l;
      }
      for (int i = 0; i < kPoints; ++i) {
        if (k == 0) {
          ids.push_back(map.add_point(truth[static_cast<std::size_t>(i)], kid, i));
        } else {
          map.add_observation(ids[static_cast<std::size_t>(i)], kid, i);
        }
      }
    }
    for (int k = 0; k < kKeyframes; ++k) map.update_connections(k, 5);
    EXPECT_TRUE(local_bundle_adjustment(map, kKeyframes - 1, cam).ran);
    double worst = 0.0;
    for (int k = 1; k < kKeyframes; ++k) {
      worst = std::max(
          worst, (map.keyframe(k)->T_w_c.so3().inverse() * poses[static_cast<std::size_t>(k)].so3())
                     .angle());
    }
    return worst * 180 / M_PI;
  };
  const double vision_only = build(false), with_gyro = build(true);
  EXPECT_GT(vision_only, 0.1);
  EXPECT_LT(with_gyro, 0.03) << "vision only: " << vision_only << " deg";
}

TEST(LocalBa, CondensedFixedViewsSolveAsTheViewsThemselves) {
  // The fixed keyframes' views of a point depend on the point alone; replaced by their robust
  // Gauss-Newton model per point, the window's solution is the one the views give. A few views
  // are gross outliers (40 px off), which both must drop. (Where fixed keyframes and points
  // disagree by centimetres, as in no settled map, the model taken at a stage's start is
  // correspondingly less exact.)
  const PinholeCamera cam = camera();
  std::mt19937 rng(9);
  std::normal_distribution<double> px_noise(0.0, 0.7), n01(0.0, 1.0);
  std::uniform_real_distribution<double> ux(-2.0, 2.0), uy(-1.5, 1.5), uz(3.0, 6.0), u01(0, 1);
  const int kPoints = 150, kKeyframes = 30;
  std::vector<Vec3> truth;
  for (int i = 0; i < kPoints; ++i) truth.emplace_back(ux(rng), uy(rng), uz(rng));
  Map map;
  std::vector<PointId> ids(kPoints, kNoPoint);
  std::vector<SE3> poses;
  for (int k = 0; k < kKeyframes; ++k) {
    poses.emplace_back(SO3::exp(Vec3(0.0, 0.02 * std::sin(0.4 * k), 0.0)),
                       Vec3(0.3 * std::sin(0.3 * k), 0.05 * std::cos(0.7 * k), 0.0));
    FrameFeatures f = observe(cam, poses.back().inverse(), truth, px_noise, n01, 0.003, rng);
    for (auto& kp : f.keypoints) {
      if (u01(rng) < 0.02) kp.un.x() += 40.0;
    }
    // A map that earlier adjustments left consistent, and a window that has yet to settle.
    const double off = k < kKeyframes - 5 ? 0.0 : 0.01;
    const KeyframeId kid =
        map.add_keyframe(k, SE3::exp(Vec6(off * Vec6::Random())) * poses.back(), f);
    for (int i = 0; i < kPoints; ++i) {
      const auto u = static_cast<std::size_t>(i);
      if (k < kKeyframes - 5 && u01(rng) < 0.4) continue;
      if (ids[u] == kNoPoint) {
        ids[u] = map.add_point(truth[u] + 0.002 * Vec3(n01(rng), n01(rng), n01(rng)), kid, i);
      } else {
        map.add_observation(ids[u], kid, i);
      }
    }
  }
  for (int k = 0; k < kKeyframes; ++k) map.update_connections(k);
  LocalBaOptions options;
  options.window = 5;
  const auto pb = gather_local_ba(map, kKeyframes - 1, options);
  ASSERT_TRUE(pb);
  ASSERT_GT(pb->fixed.size(), 20u);
  options.condense_fixed_views = false;  // every view its own residual
  const LocalBaSolution views = solve_local_ba(*pb, cam, options);
  options.condense_fixed_views = true;
  const LocalBaSolution condensed = solve_local_ba(*pb, cam, options);
  ASSERT_TRUE(views.result.ran && condensed.result.ran);
  ASSERT_EQ(views.T_c_w.size(), condensed.T_c_w.size());
  double worst_pose = 0.0, worst_point = 0.0, moved = 0.0;
  for (const auto& [k, T] : views.T_c_w) {
    worst_pose = std::max(
        worst_pose,
        (T.inverse().translation() - condensed.T_c_w.at(k).inverse().translation()).norm());
    moved = std::max(moved,
                     (T.inverse().translation() - pb->T_c_w.at(k).inverse().translation()).norm());
  }
  for (const auto& [p, x] : views.points) {
    worst_point = std::max(worst_point, (x - condensed.points.at(p)).norm());
  }
  EXPECT_GT(moved, 3e-3) << "the window must have had somewhere to go";
  // A model taken where the map had settled is exact to first order: the window lands within
  // 0.01 mm, the points within half a millimetre (of a window that moved centimetres).
  EXPECT_LT(worst_pose, 2e-5) << "moved " << moved;
  EXPECT_LT(worst_point, 1e-3);
  // The outliers found are the same views.
  auto sorted = [](std::vector<std::pair<PointId, KeyframeId>> v) {
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_GT(views.outliers.size(), 20u);
  EXPECT_EQ(sorted(views.outliers), sorted(condensed.outliers));
}

TEST(Map, ErasingAKeyframeCarriesItsGyroLinkThrough) {
  Map map;
  const SO3 a = SO3::exp(Vec3(0.1, 0, 0)), b = SO3::exp(Vec3(0, 0.2, 0));
  for (int k = 0; k < 3; ++k) map.add_keyframe(k, SE3(), FrameFeatures{});
  auto link = [](KeyframeId from, const SO3& R, double dt, double sigma) {
    GyroLink l;
    l.from = from;
    l.R_c_from = R.matrix();
    l.dt_s = dt;
    l.sigma_rad = sigma;
    return l;
  };
  map.keyframe(1)->gyro = link(0, a, 0.5, 3e-4);
  map.keyframe(2)->gyro = link(1, b, 0.25, 4e-4);
  map.keyframe(2)->gyro->imu = PreintegratedImu{};
  map.erase_keyframe(1);
  ASSERT_TRUE(map.keyframe(2)->gyro);
  const GyroLink& l = *map.keyframe(2)->gyro;
  // A pre-integration does not compose through another keyframe's: the inertial edge goes.
  EXPECT_FALSE(l.imu);
  EXPECT_EQ(l.from, 0);
  EXPECT_LT((SO3(l.R_c_from).inverse() * b * a).angle(), 1e-12);
  EXPECT_DOUBLE_EQ(l.dt_s, 0.75);
  EXPECT_NEAR(l.sigma_rad, 5e-4, 1e-12);
  map.erase_keyframe(0);  // nothing before it: the link goes
  EXPECT_FALSE(map.keyframe(2)->gyro);
}

}  // namespace
}  // namespace kestrel::mapping
