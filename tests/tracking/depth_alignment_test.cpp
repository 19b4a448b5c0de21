#include "tracking/depth_alignment.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/so3.hpp"
#include "synthetic_scene.hpp"

namespace kestrel::tracking {
namespace {

constexpr double kScale = 5000.0;

struct Plane {
  Vec3 n;    // unit normal
  double d;  // n . X = d
};

// Depth of the nearest plane along every pixel's ray, with Gaussian noise of sigma_m.
Image render(const std::vector<Plane>& planes, const SE3& T_w_c, const PinholeCamera& cam,
             double sigma_m, unsigned seed) {
  Image im = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_m);
  for (int v = 0; v < cam.height; ++v) {
    auto* row = im.row<std::uint16_t>(v);
    for (int u = 0; u < cam.width; ++u) {
      const Vec3 ray((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
      const Vec3 dir = T_w_c.so3() * ray;
      double best = 1e9;
      for (const Plane& p : planes) {
        const double den = p.n.dot(dir);
        if (std::abs(den) < 1e-9) continue;
        const double s = (p.d - p.n.dot(T_w_c.translation())) / den;
        if (s > 0.0 && s < best) best = s;
      }
      const double z = best < 20.0 ? best + noise(rng) : 0.0;
      row[u] = static_cast<std::uint16_t>(std::clamp(z * kScale, 0.0, 65535.0));
    }
  }
  return im;
}

struct Case {
  SE3 T_w_ref, T_w_cur;
  Image ref, cur;
};

Case make_case(const std::vector<Plane>& planes, const PinholeCamera& cam) {
  Case c;
  c.T_w_ref = test::camera_facing_x(Vec3(0, 0, 1.2), 0.0);
  c.T_w_cur = test::camera_facing_x(Vec3(0.04, -0.03, 1.21), 0.02);
  c.ref = render(planes, c.T_w_ref, cam, 0.02, 1);
  c.cur = render(planes, c.T_w_cur, cam, 0.02, 2);
  return c;
}

const std::vector<Plane> kWall = {{Vec3(-1, 0, 0), -3.0}};
// The wall, the floor and a side wall: every direction is seen.
const std::vector<Plane> kCorner = {
    {Vec3(-1, 0, 0), -3.0}, {Vec3(0, 0, 1), 0.0}, {Vec3(0, -1, 0), -1.5}};

DepthAlignmentPrior off_prior(const Case& c, const Vec3& dt_w, double dyaw) {
  const SE3 wrong(SO3::exp(Vec3(0, 0, dyaw)) * c.T_w_cur.so3(), c.T_w_cur.translation() + dt_w);
  DepthAlignmentPrior p;
  p.T_ref_cur = c.T_w_ref.inverse() * wrong;
  p.rotation_sigma = 0.02;
  p.translation_sigma = 0.05;
  return p;
}

TEST(DepthAlignment, RecoversTheMotionWhereDepthSeesEveryDirection) {
  const PinholeCamera cam;
  const Case c = make_case(kCorner, cam);
  const DepthAlignmentPrior prior = off_prior(c, Vec3(0.02, 0.03, -0.02), 0.01);
  const DepthAlignmentResult r = align_depth(c.ref, kScale, c.cur, kScale, cam, prior);
  ASSERT_TRUE(r.ok);
  const SE3 T_w_est = c.T_w_ref * r.T_ref_cur;
  EXPECT_LT((T_w_est.translation() - c.T_w_cur.translation()).norm(), 0.003);
  EXPECT_LT((T_w_est.so3() * c.T_w_cur.so3().inverse()).log().norm(), 1e-3);
  EXPECT_GT(r.weakest_translation_information, 1e6);
  EXPECT_GT(r.weakest_information, DepthAlignmentOptions{}.min_information);
  EXPECT_LT(r.rms_sigmas, 2.0);
}

// Facing a bare wall, depth fixes the distance to it and leaves the slide along it to the prior.
TEST(DepthAlignment, OnABareWallCorrectsOnlyTheDistance) {
  const PinholeCamera cam;
  const Case c = make_case(kWall, cam);
  const Vec3 off(0.03, 0.01, -0.01);  // world x is the wall's normal
  DepthAlignmentPrior prior = off_prior(c, off, 0.0);
  prior.rotation_sigma = 1e-3;
  prior.translation_sigma = 0.01;
  const DepthAlignmentResult r = align_depth(c.ref, kScale, c.cur, kScale, cam, prior);
  ASSERT_TRUE(r.ok);
  const Vec3 err = (c.T_w_ref * r.T_ref_cur).translation() - c.T_w_cur.translation();
  EXPECT_LT(std::abs(err.x()), 0.003);
  EXPECT_NEAR(err.y(), off.y(), 0.004);
  EXPECT_NEAR(err.z(), off.z(), 0.004);
  // Along the wall depth knows far less than across it (a few centimetres against a fraction of
  // a millimetre).
  EXPECT_LT(r.weakest_translation_information, 1e4);
  EXPECT_LT(r.weakest_information, DepthAlignmentOptions{}.min_information);
}

// A mover's depth moves on its own: its box is left out. Here the right fifth of the current view
// holds surfaces pushed 4 cm away, as a walker's would be a frame later.
TEST(DepthAlignment, LeavesTheMoversBoxesOut) {
  const PinholeCamera cam;
  Case c = make_case(kCorner, cam);
  for (int v = 0; v < cam.height; ++v) {
    auto* row = c.cur.row<std::uint16_t>(v);
    for (int u = 512; u < cam.width; ++u) {
      if (row[u] > 0) row[u] = static_cast<std::uint16_t>(row[u] + 0.04 * kScale);
    }
  }
  const DepthAlignmentPrior prior = off_prior(c, Vec3(0.01, 0.01, 0.0), 0.0);
  const auto error = [&](const DepthAlignmentResult& r) {
    return ((c.T_w_ref * r.T_ref_cur).translation() - c.T_w_cur.translation()).norm();
  };
  const DepthAlignmentResult with_box =
      align_depth(c.ref, kScale, c.cur, kScale, cam, prior, {}, {PixelBox{512, 0, 640, 480}});
  ASSERT_TRUE(with_box.ok);
  EXPECT_LT(error(with_box), 0.004);
  const DepthAlignmentResult without = align_depth(c.ref, kScale, c.cur, kScale, cam, prior);
  EXPECT_TRUE(!without.ok || error(without) > 0.01);
}

TEST(DepthAlignment, WithoutUsableDepthKeepsThePrior) {
  const PinholeCamera cam;
  const Case c = make_case(kCorner, cam);
  const DepthAlignmentPrior prior = off_prior(c, Vec3(0.02, 0.0, 0.0), 0.0);
  const Image empty = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);  // all zero
  for (const auto& [a, b] : {std::pair{&empty, &c.cur}, std::pair{&c.ref, &empty}}) {
    const DepthAlignmentResult r = align_depth(*a, kScale, *b, kScale, cam, prior);
    EXPECT_FALSE(r.ok);
    EXPECT_LT((r.T_ref_cur.translation() - prior.T_ref_cur.translation()).norm(), 1e-12);
  }
  const Image color = Image::allocate(cam.width, cam.height, 3, PixelType::kU8);
  EXPECT_FALSE(align_depth(color, kScale, c.cur, kScale, cam, prior).ok);
  EXPECT_FALSE(align_depth(c.ref, 0.0, c.cur, kScale, cam, prior).ok);
}

// A wrong prediction that the depth contradicts (the wall 15 cm nearer than seen) is refused
// rather than bent into a pose: every pair falls outside the association gate.
TEST(DepthAlignment, RefusesAPredictionFarOffAlongTheNormal) {
  const PinholeCamera cam;
  const Case c = make_case(kWall, cam);
  DepthAlignmentPrior prior = off_prior(c, Vec3(0.15, 0.0, 0.0), 0.0);
  prior.translation_sigma = 0.001;
  const DepthAlignmentResult r = align_depth(c.ref, kScale, c.cur, kScale, cam, prior);
  EXPECT_FALSE(r.ok);
}

}  // namespace
}  // namespace kestrel::tracking
