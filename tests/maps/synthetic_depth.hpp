#pragma once
// Depth images of simple scenes for the map tests: a camera at `eye` looking along world +x
// (z up) at a wall x = wall_x, optionally with a box-shaped "walker" in front of it.
#include <cmath>
#include <cstdint>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/se3.hpp"

namespace kestrel::test {

inline PinholeCamera small_camera() {
  PinholeCamera c;
  c.width = 160;
  c.height = 120;
  c.fx = c.fy = 131.25;
  c.cx = 79.5;
  c.cy = 59.5;
  return c;
}

// Camera z (forward) along world +x, camera x (right) along world -y, camera y (down) along -z.
inline SE3 looking_along_x(const Vec3& eye) {
  Mat3 R;
  R << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return SE3(SO3(R), eye);
}

struct Walker {
  bool present = false;
  double x = 1.5;                    // world x of its front face
  double y_min = -0.3, y_max = 0.3;  // world y extent
  double z_max = 1.8;                // from the floor (z = 0)
};

// Ray-traced depth (depth_scale 5000) of the wall x = wall_x and the walker, seen from T_w_c.
inline Image wall_depth(const PinholeCamera& cam, const SE3& T_w_c, double wall_x,
                        const Walker& walker, std::vector<std::uint8_t>* walker_pixels = nullptr) {
  Image d = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);
  if (walker_pixels) walker_pixels->assign(static_cast<std::size_t>(cam.width) * cam.height, 0);
  for (int v = 0; v < cam.height; ++v) {
    auto* row = d.row<std::uint16_t>(v);
    for (int u = 0; u < cam.width; ++u) {
      const Vec3 ray_w = T_w_c.rotation() * cam.unproject(Vec2(u, v));
      const Vec3 o = T_w_c.translation();
      double depth = (wall_x - o.x()) / ray_w.x();  // camera z per unit ray (ray z_c = 1)
      if (walker.present) {
        const double s = (walker.x - o.x()) / ray_w.x();
        const Vec3 p = o + s * ray_w;
        if (s > 0 && s < depth && p.y() >= walker.y_min && p.y() <= walker.y_max && p.z() >= 0 &&
            p.z() <= walker.z_max) {
          depth = s;
          if (walker_pixels) (*walker_pixels)[static_cast<std::size_t>(v) * cam.width + u] = 1;
        }
      }
      row[u] = static_cast<std::uint16_t>(std::lround(depth * 5000.0));
    }
  }
  return d;
}

}  // namespace kestrel::test
