#pragma once
#include "core/camera.hpp"
#include "core/se3.hpp"

namespace kestrel {

struct StereoRig {
  PinholeCamera left;
  PinholeCamera right;
  SE3 T_left_right;  // maps right-camera points into the left camera

  double baseline() const { return T_left_right.translation().norm(); }
};

}  // namespace kestrel
