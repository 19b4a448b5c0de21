// The rasterizer's depth and ids must be exact geometry: a known plane gives its depth at every
// pixel, back faces vanish, and geometry crossing the near plane is clipped, not lost.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/rasterizer.hpp"

namespace kestrel::sim {
namespace {

std::vector<Texture> one_texture() {
  std::vector<std::uint8_t> bgra(16 * 16 * 4);
  for (std::size_t i = 0; i < bgra.size(); ++i) bgra[i] = static_cast<std::uint8_t>(i * 37);
  std::vector<Texture> t;
  t.push_back(Texture::from_bgra(16, 16, bgra, false));
  return t;
}

RenderTarget target_for(const PinholeCamera& cam) {
  RenderTarget t;
  t.resize(cam.width, cam.height, 16);
  const std::uint8_t sky[3] = {0, 0, 0};
  t.clear(sky, sky);
  return t;
}

TEST(Rasterizer, TiltedPlaneHasExactDepthEverywhere) {
  PinholeCamera cam;
  const auto textures = one_texture();
  // Plane through (0,0,3) with normal n (facing the camera), as a big tiled quad.
  const Vec3 n = Vec3(0.3, -0.2, -1.0).normalized();
  const Vec3 c(0, 0, 3);
  const Vec3 e1 = n.cross(Vec3::UnitY()).normalized();
  const Vec3 e2 = n.cross(e1).normalized();
  Mesh mesh;
  const auto f = [](const Vec3& v) { return Vec3f(v.cast<float>()); };
  const double s = 6.0;
  Vec3f p[4] = {f(c - s * e1 - s * e2), f(c + s * e1 - s * e2), f(c + s * e1 + s * e2),
                f(c - s * e1 + s * e2)};
  // Order the corners so that the face points at the camera.
  if ((p[1] - p[0]).cross(p[3] - p[0]).dot(p[0]) > 0) std::swap(p[1], p[3]);
  add_quad(mesh, p[0], p[1], p[2], p[3], Vec2f::Zero(), 1.0f, 0, 7, 1.0f);
  RenderTarget t = target_for(cam);
  Rasterizer(cam).draw(mesh, textures, SE3(), t);
  double max_rel = 0.0;
  int drawn = 0;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * cam.width + x;
      ASSERT_GT(t.inv_depth[i], 0.0f) << x << "," << y;
      ASSERT_EQ(t.id[i], 7);
      const Vec3 ray = cam.unproject(Vec2(x, y));
      const double z = n.dot(c) / n.dot(ray);
      max_rel = std::max(max_rel, std::fabs(1.0 / t.inv_depth[i] - z) / z);
      ++drawn;
    }
  }
  EXPECT_EQ(drawn, cam.width * cam.height);
  EXPECT_LT(max_rel, 1e-4);
  EXPECT_EQ(t.fragments[7], static_cast<std::uint32_t>(cam.width * cam.height));
}

TEST(Rasterizer, BackFacesAreCulledAndNearGeometryIsClipped) {
  PinholeCamera cam;
  const auto textures = one_texture();
  Mesh away;
  // Normal +z: seen from behind by a camera at the origin looking along +z.
  add_quad(away, Vec3f(-1, -1, 2), Vec3f(1, -1, 2), Vec3f(1, 1, 2), Vec3f(-1, 1, 2), Vec2f::Zero(),
           1.0f, 0, 3, 1.0f);
  RenderTarget t = target_for(cam);
  Rasterizer(cam).draw(away, textures, SE3(), t);
  EXPECT_EQ(t.fragments[3], 0u);

  // A floor 1 m below the camera running from behind it to 20 m ahead (y down is +y).
  Mesh floor;
  add_quad(floor, Vec3f(-5, 1, -3), Vec3f(5, 1, -3), Vec3f(5, 1, 20), Vec3f(-5, 1, 20),
           Vec2f::Zero(), 1.0f, 0, 4, 1.0f);
  RenderTarget f = target_for(cam);
  Rasterizer(cam).draw(floor, textures, SE3(), f);
  EXPECT_GT(f.fragments[4], 0u);
  // Bottom row centre: the ray meets y = 1 at z = fy / (v - cy).
  const int v = cam.height - 1, u = cam.width / 2;
  const double z = cam.fy / (v - cam.cy);
  EXPECT_NEAR(1.0 / f.inv_depth[static_cast<std::size_t>(v) * cam.width + u], z, 1e-3 * z);
  // Above the horizon nothing is drawn.
  EXPECT_EQ(f.id[static_cast<std::size_t>(10) * cam.width + u], 0);
}

TEST(Rasterizer, SharedEdgesDrawEachPixelOnce) {
  PinholeCamera cam;
  const auto textures = one_texture();
  Mesh mesh;
  // A fan of thin triangles around a centre: overlaps or cracks would change the count.
  const int k = 37;
  const float r = 0.8f;
  for (int i = 0; i < k; ++i) {
    const double a0 = 2 * M_PI * i / k, a1 = 2 * M_PI * (i + 1) / k;
    const Vec3f c(0.01f, 0.02f, 2.0f);
    const Vec3f p0 =
        c + r * Vec3f(static_cast<float>(std::cos(a0)), static_cast<float>(std::sin(a0)), 0);
    const Vec3f p1 =
        c + r * Vec3f(static_cast<float>(std::cos(a1)), static_cast<float>(std::sin(a1)), 0);
    Triangle t{{{c, Vec2f::Zero()}, {p1, Vec2f::Zero()}, {p0, Vec2f::Zero()}},
               0,
               static_cast<std::uint16_t>(1 + i % 2),
               1.0f};
    mesh.push_back(t);
  }
  RenderTarget t = target_for(cam);
  Rasterizer(cam).draw(mesh, textures, SE3(), t);
  std::size_t covered = 0;
  for (auto id : t.id) covered += id != 0;
  EXPECT_EQ(covered, static_cast<std::size_t>(t.fragments[1] + t.fragments[2]));
  // Area of the 37-gon of radius r at z = 2 in pixels (inside the image).
  const double area = 0.5 * k * std::sin(2 * M_PI / k) * (r * cam.fx / 2) * (r * cam.fy / 2);
  EXPECT_NEAR(static_cast<double>(covered), area, 0.01 * area);
}

}  // namespace
}  // namespace kestrel::sim
