#include "sim/mesh.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

namespace kestrel::sim {

float face_shade(const Vec3f& n) {
  const Vec3f sun = Vec3f(0.35f, 0.55f, 0.76f).normalized();
  const float ambient = 0.6f + 0.15f * n.z();
  return std::clamp(ambient + 0.4f * std::max(0.0f, n.dot(sun)), 0.2f, 1.0f);
}

void add_quad(Mesh& mesh, const Vec3f& p0, const Vec3f& p1, const Vec3f& p2, const Vec3f& p3,
              const Vec2f& uv0, float texture_scale, int texture, std::uint16_t instance,
              float max_tile, float shade_gain) {
  const Vec3f eu = p1 - p0;
  const Vec3f ev = p3 - p0;
  const float lu = eu.norm(), lv = ev.norm();
  const int nu = std::max(1, static_cast<int>(std::ceil(lu / max_tile)));
  const int nv = std::max(1, static_cast<int>(std::ceil(lv / max_tile)));
  const Vec3f n = eu.cross(ev).normalized();
  const float shade = std::clamp(face_shade(n) * shade_gain, 0.0f, 1.0f);
  // Bilinear so that non-planar (never used) or trapezoid quads still close up.
  const auto point = [&](float a, float b) {
    return ((1 - a) * (1 - b)) * p0 + (a * (1 - b)) * p1 + (a * b) * p2 + ((1 - a) * b) * p3;
  };
  const auto uv = [&](float a, float b) {
    return Vec2f(uv0.x() + a * lu / texture_scale, uv0.y() + b * lv / texture_scale);
  };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const float a0 = static_cast<float>(i) / nu, a1 = static_cast<float>(i + 1) / nu;
      const float b0 = static_cast<float>(j) / nv, b1 = static_cast<float>(j + 1) / nv;
      const Vertex v00{point(a0, b0), uv(a0, b0)}, v10{point(a1, b0), uv(a1, b0)};
      const Vertex v11{point(a1, b1), uv(a1, b1)}, v01{point(a0, b1), uv(a0, b1)};
      mesh.push_back(Triangle{{v00, v10, v11}, texture, instance, shade});
      mesh.push_back(Triangle{{v00, v11, v01}, texture, instance, shade});
    }
  }
}

void add_box(Mesh& mesh, const Vec3f& center, const Vec3f& size, float yaw, int texture,
             std::uint16_t instance, float texture_scale, float max_tile, BoxFaces faces,
             float shade_gain) {
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Vec3f::UnitZ()).toRotationMatrix();
  const Vec3f h = 0.5f * size;
  const auto corner = [&](float sx, float sy, float sz) {
    return Vec3f(center + R * Vec3f(sx * h.x(), sy * h.y(), sz * h.z()));
  };
  // Each face listed counter-clockwise seen from outside.
  struct Face {
    Vec3f a, b, c, d;
    bool bottom, top;
  };
  const Face list[6] = {
      {corner(-1, -1, -1), corner(1, -1, -1), corner(1, -1, 1), corner(-1, -1, 1), false, false},
      {corner(1, -1, -1), corner(1, 1, -1), corner(1, 1, 1), corner(1, -1, 1), false, false},
      {corner(1, 1, -1), corner(-1, 1, -1), corner(-1, 1, 1), corner(1, 1, 1), false, false},
      {corner(-1, 1, -1), corner(-1, -1, -1), corner(-1, -1, 1), corner(-1, 1, 1), false, false},
      {corner(-1, -1, 1), corner(1, -1, 1), corner(1, 1, 1), corner(-1, 1, 1), false, true},
      {corner(-1, 1, -1), corner(1, 1, -1), corner(1, -1, -1), corner(-1, -1, -1), true, false},
  };
  int k = 0;
  for (const Face& f : list) {
    ++k;
    if ((f.bottom && faces.skip_bottom) || (f.top && faces.skip_top)) continue;
    // Each face starts elsewhere in the texture so that the sides of a box do not repeat.
    const Vec2f uv0(0.37f * k, 0.61f * k);
    if (faces.inward) {
      add_quad(mesh, f.d, f.c, f.b, f.a, uv0, texture_scale, texture, instance, max_tile,
               shade_gain);
    } else {
      add_quad(mesh, f.a, f.b, f.c, f.d, uv0, texture_scale, texture, instance, max_tile,
               shade_gain);
    }
  }
}

}  // namespace kestrel::sim
