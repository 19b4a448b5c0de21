#include "synthetic_scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/so3.hpp"
#include "io/image_io.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::test {

SyntheticScene SyntheticScene::office() {
  SyntheticScene s;
  for (const char* name : {"horses.jpg", "person.jpg", "000004.jpg", "dog.jpg"}) {
    const Image im =
        io::load_image(shared_data(std::string("images/") + name).string(), io::ImageKind::kGrey);
    Texture t;
    t.width = im.width;
    t.height = im.height;
    t.grey.resize(static_cast<std::size_t>(im.width) * im.height);
    for (int y = 0; y < im.height; ++y) {
      for (int x = 0; x < im.width; ++x) {
        t.grey[static_cast<std::size_t>(y) * im.width + x] = im.row<std::uint8_t>(y)[x];
      }
    }
    s.textures_.push_back(std::move(t));
  }
  const Vec3 ex = Vec3::UnitX(), ey = Vec3::UnitY(), ez = Vec3::UnitZ();
  s.planes_.push_back({Vec3(-3.0, -2.2, 3.0), ex, ey, 6.0, 3.2, 0.004, 0});   // back wall
  s.planes_.push_back({Vec3(-0.6, -0.4, 1.5), ex, ey, 0.8, 0.8, 0.0015, 1});  // box front
  s.planes_.push_back({Vec3(0.2, -0.4, 1.5), ez, ey, 0.6, 0.8, 0.0015, 2});   // box side
  s.planes_.push_back({Vec3(-3.0, 1.0, 0.3), ex, ez, 6.0, 2.7, 0.004, 3});    // floor
  return s;
}

RgbdFrame SyntheticScene::render(const PinholeCamera& cam, const SE3& T_w_c, Timestamp t) const {
  RgbdFrame f;
  f.t = t;
  f.color = Image::allocate(cam.width, cam.height, 1, PixelType::kU8);
  f.depth = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);
  f.depth_scale = 5000.0;
  const Mat3 R = T_w_c.rotation();
  const Vec3 c = T_w_c.translation();
  for (int y = 0; y < cam.height; ++y) {
    auto* grey = f.color.row<std::uint8_t>(y);
    auto* depth = f.depth.row<std::uint16_t>(y);
    for (int x = 0; x < cam.width; ++x) {
      const Vec3 d_c((x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, 1.0);
      const Vec3 d_w = R * d_c;
      double best = std::numeric_limits<double>::infinity();
      float value = 0.0f;
      for (const Plane& p : planes_) {
        const Vec3 n = p.u.cross(p.v);
        const double den = n.dot(d_w);
        if (std::fabs(den) < 1e-9) continue;
        const double s = n.dot(p.origin - c) / den;  // = camera depth, since d_c.z = 1
        if (s <= 0.05 || s >= best) continue;
        const Vec3 q = c + s * d_w - p.origin;
        const double a = q.dot(p.u), b = q.dot(p.v);
        if (a < 0 || b < 0 || a > p.size_u || b > p.size_v) continue;
        const Texture& tex = textures_[static_cast<std::size_t>(p.texture)];
        // Bilinear, tiled.
        const double tu = a / p.texel, tv = b / p.texel;
        const double fu = std::floor(tu), fv = std::floor(tv);
        const double wu = tu - fu, wv = tv - fv;
        auto at = [&](long i, long j) {
          const long ii = ((i % tex.width) + tex.width) % tex.width;
          const long jj = ((j % tex.height) + tex.height) % tex.height;
          return tex.grey[static_cast<std::size_t>(jj * tex.width + ii)];
        };
        const long i0 = static_cast<long>(fu), j0 = static_cast<long>(fv);
        value =
            static_cast<float>((1 - wu) * (1 - wv) * at(i0, j0) + wu * (1 - wv) * at(i0 + 1, j0) +
                               (1 - wu) * wv * at(i0, j0 + 1) + wu * wv * at(i0 + 1, j0 + 1));
        best = s;
      }
      grey[x] = static_cast<std::uint8_t>(std::lround(std::clamp(value, 0.0f, 255.0f)));
      depth[x] = std::isfinite(best) && best * 5000.0 < 65535.0
                     ? static_cast<std::uint16_t>(std::lround(best * 5000.0))
                     : 0;
    }
  }
  return f;
}

SE3 camera_facing_x(const Vec3& t, double yaw) {
  Mat3 R_w_c;
  R_w_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return SE3(SO3::exp(Vec3(0, 0, yaw)) * SO3(R_w_c), t);
}

std::vector<SE3> smooth_path(int n) {
  std::vector<SE3> path;
  for (int i = 0; i < n; ++i) {
    const double s = n > 1 ? static_cast<double>(i) / (n - 1) : 0.0;
    const double w = 2.0 * M_PI * s;
    const Vec3 p(0.25 * std::sin(0.8 * w), 0.05 * std::sin(w), 0.3 * s);
    const Vec3 rot(0.04 * std::sin(w), 0.08 * std::sin(0.8 * w), 0.02 * std::sin(0.5 * w));
    path.emplace_back(SO3::exp(rot), p);
  }
  return path;
}

}  // namespace kestrel::test
