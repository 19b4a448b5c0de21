#include "sim/rasterizer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace kestrel::sim {
namespace {

constexpr int kSubBits = 8;  // fixed-point sub-pixel precision of vertex positions
constexpr float kSub = 1 << kSubBits;
// Coordinates beyond this many pixels would overflow the 64-bit edge functions' headroom; the
// scene is tiled so that this never happens, the check only keeps bad input from crashing.
constexpr float kMaxCoord = 1 << 20;

}  // namespace

void RenderTarget::resize(int w, int h, std::size_t max_instances) {
  width = w;
  height = h;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  bgr.assign(n * 3, 0);
  inv_depth.assign(n, 0.0f);
  id.assign(n, 0);
  counted.assign(n, 0);
  fragments.assign(max_instances, 0);
}

void RenderTarget::clear(const std::uint8_t top[3], const std::uint8_t bottom[3]) {
  for (int y = 0; y < height; ++y) {
    const int a = height > 1 ? (256 * y) / (height - 1) : 0;
    std::uint8_t c[3];
    for (int k = 0; k < 3; ++k)
      c[k] = static_cast<std::uint8_t>((top[k] * (256 - a) + bottom[k] * a) >> 8);
    std::uint8_t* row = bgr.data() + static_cast<std::size_t>(y) * width * 3;
    for (int x = 0; x < width; ++x) {
      row[3 * x] = c[0];
      row[3 * x + 1] = c[1];
      row[3 * x + 2] = c[2];
    }
  }
  std::fill(inv_depth.begin(), inv_depth.end(), 0.0f);
  std::fill(id.begin(), id.end(), std::uint16_t{0});
  std::fill(counted.begin(), counted.end(), std::uint16_t{0});
  std::fill(fragments.begin(), fragments.end(), 0u);
}

Rasterizer::Rasterizer(const PinholeCamera& camera, float near_plane)
    : fx_(static_cast<float>(camera.fx)),
      fy_(static_cast<float>(camera.fy)),
      cx_(static_cast<float>(camera.cx)),
      cy_(static_cast<float>(camera.cy)),
      width_(camera.width),
      height_(camera.height),
      near_(near_plane) {}

void Rasterizer::draw(const Mesh& mesh, const std::vector<Texture>& textures, const SE3& T_c_w,
                      RenderTarget& target) const {
  const Eigen::Matrix3f R = T_c_w.rotation().cast<float>();
  const Vec3f t = T_c_w.translation().cast<float>();
  // Frustum side planes in camera coordinates (inside: dot >= 0), half a pixel of margin.
  const float l = -0.5f - 1.0f, r = static_cast<float>(width_) - 0.5f + 1.0f;
  const float tp = -0.5f - 1.0f, bt = static_cast<float>(height_) - 0.5f + 1.0f;
  for (const Triangle& tri : mesh) {
    ClipVertex cv[3];
    Vec3f pc[3];
    for (int k = 0; k < 3; ++k) {
      pc[k] = R * tri.v[k].p + t;
      cv[k] = {pc[k].x(), pc[k].y(), pc[k].z(), tri.v[k].uv.x(), tri.v[k].uv.y()};
    }
    // Back face: the normal points away from the camera centre.
    if ((pc[1] - pc[0]).cross(pc[2] - pc[0]).dot(pc[0]) >= 0.0f) continue;
    int out_near = 0, out_l = 0, out_r = 0, out_t = 0, out_b = 0;
    for (int k = 0; k < 3; ++k) {
      const float x = pc[k].x(), y = pc[k].y(), z = pc[k].z();
      out_near += z < near_;
      out_l += fx_ * x + (cx_ - l) * z < 0.0f;
      out_r += fx_ * x + (cx_ - r) * z > 0.0f;
      out_t += fy_ * y + (cy_ - tp) * z < 0.0f;
      out_b += fy_ * y + (cy_ - bt) * z > 0.0f;
    }
    if (out_near == 3 || out_l == 3 || out_r == 3 || out_t == 3 || out_b == 3) continue;
    const Texture& tex = textures[static_cast<std::size_t>(tri.texture)];
    if (out_near == 0) {
      raster_triangle(cv[0], cv[1], cv[2], tex, tri.instance, tri.shade, target);
      continue;
    }
    // Sutherland-Hodgman against z = near: at most four vertices remain.
    ClipVertex poly[4];
    int n = 0;
    for (int k = 0; k < 3; ++k) {
      const ClipVertex& a = cv[k];
      const ClipVertex& b = cv[(k + 1) % 3];
      const bool ain = a.z >= near_, bin = b.z >= near_;
      if (ain) poly[n++] = a;
      if (ain != bin) {
        const float s = (near_ - a.z) / (b.z - a.z);
        poly[n++] = {a.x + s * (b.x - a.x), a.y + s * (b.y - a.y), near_, a.u + s * (b.u - a.u),
                     a.v + s * (b.v - a.v)};
      }
    }
    for (int k = 1; k + 1 < n; ++k) {
      raster_triangle(poly[0], poly[k], poly[k + 1], tex, tri.instance, tri.shade, target);
    }
  }
}

void Rasterizer::raster_triangle(const ClipVertex& a, const ClipVertex& b, const ClipVertex& c,
                                 const Texture& tex, std::uint16_t instance, float shade,
                                 RenderTarget& target) const {
  // Screen position and the perspective-correct attributes 1/z, u/z, v/z.
  ClipVertex s[3];
  const ClipVertex* in[3] = {&a, &b, &c};
  for (int k = 0; k < 3; ++k) {
    const float w = 1.0f / in[k]->z;
    s[k] = {fx_ * in[k]->x * w + cx_, fy_ * in[k]->y * w + cy_, w, in[k]->u * w, in[k]->v * w};
    if (!(std::fabs(s[k].x) < kMaxCoord && std::fabs(s[k].y) < kMaxCoord)) return;
  }
  // Texel footprint decides the mip level: log2 of texels per pixel, per triangle.
  const float area_px =
      std::fabs((s[1].x - s[0].x) * (s[2].y - s[0].y) - (s[2].x - s[0].x) * (s[1].y - s[0].y));
  if (area_px <= 0.0f) return;
  const float du1 = in[1]->u - in[0]->u, dv1 = in[1]->v - in[0]->v;
  const float du2 = in[2]->u - in[0]->u, dv2 = in[2]->v - in[0]->v;
  const float area_tex = std::fabs(du1 * dv2 - du2 * dv1) * static_cast<float>(tex.width()) *
                         static_cast<float>(tex.height());
  int level = 0;
  if (area_tex > area_px) {
    level = static_cast<int>(0.5f * std::log2(area_tex / area_px) + 0.3f);
    level = std::clamp(level, 0, static_cast<int>(tex.levels.size()) - 1);
  }
  const int shade256 = static_cast<int>(shade * 256.0f + 0.5f);
  if (tex.has_alpha) {
    fill<true>(s, tex.levels[static_cast<std::size_t>(level)], instance, shade256, target);
  } else {
    fill<false>(s, tex.levels[static_cast<std::size_t>(level)], instance, shade256, target);
  }
}

template <bool kAlpha>
void Rasterizer::fill(const ClipVertex* sv, const TextureLevel& level, std::uint16_t instance,
                      int shade256, RenderTarget& target) const {
  std::int64_t X[3], Y[3];
  for (int k = 0; k < 3; ++k) {
    X[k] = std::llround(sv[k].x * kSub);
    Y[k] = std::llround(sv[k].y * kSub);
  }
  std::int64_t area = (X[1] - X[0]) * (Y[2] - Y[0]) - (X[2] - X[0]) * (Y[1] - Y[0]);
  if (area == 0) return;
  int i1 = 1, i2 = 2;
  if (area < 0) {
    std::swap(i1, i2);
    area = -area;
  }
  const int idx[3] = {0, i1, i2};
  const std::int64_t min_x = std::min({X[0], X[1], X[2]}), max_x = std::max({X[0], X[1], X[2]});
  const std::int64_t min_y = std::min({Y[0], Y[1], Y[2]}), max_y = std::max({Y[0], Y[1], Y[2]});
  const int x0 =
      static_cast<int>(std::max<std::int64_t>(0, (min_x + (1 << kSubBits) - 1) >> kSubBits));
  const int x1 = static_cast<int>(std::min<std::int64_t>(width_ - 1, max_x >> kSubBits));
  const int y0 =
      static_cast<int>(std::max<std::int64_t>(0, (min_y + (1 << kSubBits) - 1) >> kSubBits));
  const int y1 = static_cast<int>(std::min<std::int64_t>(height_ - 1, max_y >> kSubBits));
  if (x0 > x1 || y0 > y1) return;

  // Edge k runs from vertex idx[k] to idx[k+1]; inside means E >= 0 (> 0 off the top-left).
  std::int64_t ex[3], ey[3], e_row[3];
  for (int k = 0; k < 3; ++k) {
    const int a = idx[k], b = idx[(k + 1) % 3];
    const std::int64_t dx = X[b] - X[a], dy = Y[b] - Y[a];
    const bool top_left = (dy == 0 && dx > 0) || dy < 0;
    const std::int64_t px = static_cast<std::int64_t>(x0) << kSubBits;
    const std::int64_t py = static_cast<std::int64_t>(y0) << kSubBits;
    e_row[k] = dx * (py - Y[a]) - dy * (px - X[a]) - (top_left ? 0 : 1);
    ex[k] = -dy << kSubBits;
    ey[k] = dx << kSubBits;
  }
  // Attribute planes f = f0 + fdx (x - x0) + fdy (y - y0) on the snapped vertex positions.
  const double xs0 = static_cast<double>(X[0]) / kSub, ys0 = static_cast<double>(Y[0]) / kSub;
  const double xs1 = static_cast<double>(X[1]) / kSub - xs0,
               ys1 = static_cast<double>(Y[1]) / kSub - ys0;
  const double xs2 = static_cast<double>(X[2]) / kSub - xs0,
               ys2 = static_cast<double>(Y[2]) / kSub - ys0;
  const double det = xs1 * ys2 - xs2 * ys1;
  const auto plane = [&](float f0, float f1, float f2, double& at_origin, double& gx, double& gy) {
    const double d1 = f1 - f0, d2 = f2 - f0;
    gx = (d1 * ys2 - d2 * ys1) / det;
    gy = (d2 * xs1 - d1 * xs2) / det;
    at_origin = f0 + gx * (x0 - xs0) + gy * (y0 - ys0);
  };
  double w0, wx, wy, u0, ux, uy, v0, vx, vy;
  plane(sv[0].z, sv[1].z, sv[2].z, w0, wx, wy);
  plane(sv[0].u, sv[1].u, sv[2].u, u0, ux, uy);
  plane(sv[0].v, sv[1].v, sv[2].v, v0, vx, vy);

  const int tw = level.width, th = level.height;
  const int wmask = tw - 1, hmask = th - 1;
  // Adding a large multiple of the texture size before truncating floors negative coordinates.
  const float bias_u = static_cast<float>(tw) * 4096.0f, bias_v = static_cast<float>(th) * 4096.0f;
  const std::uint8_t* texels = level.bgra.data();
  const int W = target.width;
  std::uint32_t* frag = target.fragments.data();
  const std::size_t n_frag = target.fragments.size();
  std::uint32_t frag_count = 0;

  for (int y = y0; y <= y1; ++y) {
    std::int64_t e0 = e_row[0], e1 = e_row[1], e2 = e_row[2];
    const double dy = y - y0;
    float w = static_cast<float>(w0 + wy * dy);
    float uw = static_cast<float>(u0 + uy * dy);
    float vw = static_cast<float>(v0 + vy * dy);
    const float fwx = static_cast<float>(wx), fux = static_cast<float>(ux),
                fvx = static_cast<float>(vx);
    const std::size_t row = static_cast<std::size_t>(y) * W;
    for (int x = x0; x <= x1; ++x) {
      if ((e0 | e1 | e2) >= 0) {
        const float z = 1.0f / w;
        const int tu = static_cast<int>(uw * z * static_cast<float>(tw) + bias_u) & wmask;
        const int tv = static_cast<int>(vw * z * static_cast<float>(th) + bias_v) & hmask;
        const std::uint8_t* texel = texels + (static_cast<std::size_t>(tv) * tw + tu) * 4;
        bool keep = true;
        if constexpr (kAlpha) keep = texel[3] >= 128;
        if (keep) {
          const std::size_t i = row + x;
          if (target.counted[i] != instance) {
            target.counted[i] = instance;
            ++frag_count;
          }
          if (w > target.inv_depth[i]) {
            target.inv_depth[i] = w;
            target.id[i] = instance;
            std::uint8_t* px = target.bgr.data() + 3 * i;
            px[0] = static_cast<std::uint8_t>((texel[0] * shade256) >> 8);
            px[1] = static_cast<std::uint8_t>((texel[1] * shade256) >> 8);
            px[2] = static_cast<std::uint8_t>((texel[2] * shade256) >> 8);
          }
        }
      }
      e0 += ex[0];
      e1 += ex[1];
      e2 += ex[2];
      w += fwx;
      uw += fux;
      vw += fvx;
    }
    e_row[0] += ey[0];
    e_row[1] += ey[1];
    e_row[2] += ey[2];
  }
  if (instance < n_frag) frag[instance] += frag_count;
}

}  // namespace kestrel::sim
