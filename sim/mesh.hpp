#pragma once
// Triangle soup the rasterizer draws, and helpers that build boxes and tiled quads from it.
// Winding: vertices are counter-clockwise seen from the visible side (right-hand normal points
// toward the viewer); back faces are culled.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace kestrel::sim {

using Vec3f = Eigen::Vector3f;
using Vec2f = Eigen::Vector2f;

struct Vertex {
  Vec3f p = Vec3f::Zero();   // world frame
  Vec2f uv = Vec2f::Zero();  // texture repeats (1 = one texture width)
};

struct Triangle {
  Vertex v[3];
  int texture = 0;
  std::uint16_t instance = 0;  // 0 = background scene; see World for the id ranges
  float shade = 1.0f;          // light reaching the surface, multiplies the texture
};

using Mesh = std::vector<Triangle>;

// How light falls on a surface of normal n (world), in [0, 1]: sky light plus a sun term.
float face_shade(const Vec3f& n);

// Quad p0 p1 p2 p3 (counter-clockwise seen from the front) mapped to uv (0,0) (su,0) (su,sv)
// (0,sv) offset by uv0, split into tiles no larger than max_tile metres so that perspective
// (mip level, near clipping) stays accurate.
void add_quad(Mesh& mesh, const Vec3f& p0, const Vec3f& p1, const Vec3f& p2, const Vec3f& p3,
              const Vec2f& uv0, float texture_scale, int texture, std::uint16_t instance,
              float max_tile, float shade_gain = 1.0f);

// Axis-aligned (in its own frame) box of size (sx sy sz) centred at c, turned by yaw about z.
// inward: faces point inside (a room). skip_bottom: leave out the face on the ground.
struct BoxFaces {
  bool inward = false;
  bool skip_bottom = true;
  bool skip_top = false;
};
void add_box(Mesh& mesh, const Vec3f& center, const Vec3f& size, float yaw, int texture,
             std::uint16_t instance, float texture_scale, float max_tile, BoxFaces faces = {},
             float shade_gain = 1.0f);

}  // namespace kestrel::sim
