#pragma once
// CPU z-buffer rasterizer: perspective-correct textured triangles, near-plane clipping,
// back-face culling, alpha-tested cut-outs, and an instance-id buffer beside colour and depth.
// Pixel centres sit at integer coordinates (OpenCV's convention, as PinholeCamera::project).
#include <cstdint>
#include <vector>

#include "core/camera.hpp"
#include "core/se3.hpp"
#include "sim/mesh.hpp"
#include "sim/texture.hpp"

namespace kestrel::sim {

struct RenderTarget {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> bgr;  // 3 bytes per pixel
  std::vector<float> inv_depth;   // 1/z, 0 where nothing was drawn
  std::vector<std::uint16_t> id;  // instance of the front-most surface
  // Pixels each instance covered before the depth test (occluded or not), for the occluded
  // fraction.
  std::vector<std::uint32_t> fragments;
  // Last instance that counted each pixel: an instance's triangles are drawn one after the
  // other, so this makes its fragment count a count of distinct pixels even where its own
  // parts overlap (a chair's seat and legs).
  std::vector<std::uint16_t> counted;

  void resize(int w, int h, std::size_t max_instances);
  // Sky gradient (top colour to horizon colour), no depth, id 0, fragment counts zeroed.
  void clear(const std::uint8_t sky_top_bgr[3], const std::uint8_t sky_bottom_bgr[3]);
};

class Rasterizer {
 public:
  Rasterizer(const PinholeCamera& camera, float near_plane = 0.05f);

  // Draws mesh seen from T_c_w (world into camera) on top of what target holds.
  void draw(const Mesh& mesh, const std::vector<Texture>& textures, const SE3& T_c_w,
            RenderTarget& target) const;

 private:
  struct ClipVertex {
    float x, y, z, u, v;
  };
  void raster_triangle(const ClipVertex& a, const ClipVertex& b, const ClipVertex& c,
                       const Texture& tex, std::uint16_t instance, float shade,
                       RenderTarget& target) const;
  template <bool kAlpha>
  void fill(const ClipVertex* s, const TextureLevel& level, std::uint16_t instance, int shade256,
            RenderTarget& target) const;

  float fx_, fy_, cx_, cy_;
  int width_, height_;
  float near_;
};

}  // namespace kestrel::sim
