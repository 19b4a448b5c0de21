#include "core/camera.hpp"

#include <gtest/gtest.h>
#include <rapidcheck.h>

#include <cmath>

namespace kestrel {
namespace {

PinholeCamera euroc_cam0() {
  PinholeCamera c;
  c.width = 752;
  c.height = 480;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.model = DistortionModel::kRadTan;
  c.dist = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0};
  return c;
}

PinholeCamera tumvi_cam0() {
  PinholeCamera c;
  c.width = 512;
  c.height = 512;
  c.fx = 190.978;
  c.fy = 190.973;
  c.cx = 254.932;
  c.cy = 256.897;
  c.model = DistortionModel::kEquidistant;
  c.dist = {0.0034823894, 0.00071506, -0.0020532362, 0.0002029343, 0.0};
  return c;
}

TEST(Camera, ProjectUnprojectRoundTripAllModels) {
  for (const PinholeCamera& cam : {PinholeCamera{}, euroc_cam0(), tumvi_cam0()}) {
    EXPECT_TRUE(rc::check("unproject(project(p)) is on p's ray", [&cam] {
      // Over the whole image at every size: rapidcheck scales inRange by the test's size, and its
      // small first sizes put every pixel in the top-left corner, beyond the fisheye's 1.4 below,
      // so that some seeds gave up on too many discards.
      const double u = *rc::gen::resize(100, rc::gen::inRange(20, cam.width - 20));
      const double v = *rc::gen::resize(100, rc::gen::inRange(20, cam.height - 20));
      // A fisheye sees past 90 degrees; such pixels have no ray with z = 1.
      const double r = std::hypot((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy);
      RC_PRE(cam.model != DistortionModel::kEquidistant || r < 1.4);
      const Vec3 ray = cam.unproject(Vec2(u, v));
      const auto uv = cam.project(ray * 3.7);
      RC_ASSERT(uv.has_value());
      RC_ASSERT((*uv - Vec2(u, v)).norm() < 1e-6);
    }));
  }
}

TEST(Camera, BehindCameraIsRejected) {
  EXPECT_FALSE(PinholeCamera{}.project(Vec3(0, 0, -1)));
  EXPECT_FALSE(PinholeCamera{}.project(Vec3(1, 1, 0)));
}

TEST(Camera, ProjectJacobianMatchesNumeric) {
  const PinholeCamera cam;
  const Vec3 p(0.3, -0.2, 2.5);
  const Mat23 J = cam.project_jacobian(p);
  for (int i = 0; i < 3; ++i) {
    const Vec3 d = Vec3::Unit(i) * 1e-6;
    const Vec2 num = (*cam.project(p + d) - *cam.project(p - d)) / 2e-6;
    EXPECT_LT((J.col(i) - num).norm(), 1e-5);
  }
}

TEST(Camera, RadTanMatchesOpenCvFormula) {
  // Hand-evaluated point for k1=-0.1 only: x' = x (1 + k1 r^2).
  PinholeCamera c;
  c.model = DistortionModel::kRadTan;
  c.dist = {-0.1, 0, 0, 0, 0};
  const Vec2 xd = c.distort(Vec2(0.2, 0.1));
  EXPECT_NEAR(xd.x(), 0.2 * (1 - 0.1 * 0.05), 1e-15);
  EXPECT_NEAR(xd.y(), 0.1 * (1 - 0.1 * 0.05), 1e-15);
}

}  // namespace
}  // namespace kestrel
