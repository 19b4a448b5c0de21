#pragma once
// A small textured world for tracking tests: photos pasted on planes at known places, rendered
// by ray-plane intersection with exact depth. Test support only (the simulator proper is sim/).
#include <string>
#include <vector>

#include "core/camera.hpp"
#include "core/frame.hpp"
#include "core/se3.hpp"

namespace kestrel::test {

class SyntheticScene {
 public:
  // A back wall at 3 m, a box whose front face is at 1.5 m, and a floor, textured with the
  // photos in shared/data/images.
  static SyntheticScene office();

  // Grey image and 16-bit depth (5000 = 1 m) seen from T_w_c.
  RgbdFrame render(const PinholeCamera& camera, const SE3& T_w_c, Timestamp t = 0) const;

 private:
  struct Plane {
    Vec3 origin;
    Vec3 u, v;  // unit axes in the plane
    double size_u = 1.0, size_v = 1.0;
    double texel = 0.005;  // metres per texture pixel (textures tile)
    int texture = 0;
  };
  struct Texture {
    int width = 0, height = 0;
    std::vector<float> grey;
  };
  std::vector<Plane> planes_;
  std::vector<Texture> textures_;
};

// A camera looking along world +x (camera z = world x, camera y = world -z), turned by yaw
// about world z: facing a wall that is a plane x = const.
SE3 camera_facing_x(const Vec3& t, double yaw);

// The camera path of the end-to-end test: smooth sideways, up-down and forward motion with a
// few degrees of rotation, n frames. World = first camera.
std::vector<SE3> smooth_path(int n);

}  // namespace kestrel::test
