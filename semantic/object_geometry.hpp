#pragma once
// An upright box fitted to an object's points (world frame, z up): the yaw whose edges the
// points hug (L-shape closeness), extents from robust percentiles along those axes, so that a few
// noisy depth readings do not inflate the box.
#include <vector>

#include <Eigen/Core>

#include "core/eigen_types.hpp"

namespace kestrel::semantic {

struct UprightBox {
  Vec3 center = Vec3::Zero();
  Vec3 size = Vec3::Zero();  // along the yaw axis (the longer side), across it, vertical
  double yaw = 0.0;          // radians about z, in (-pi/2, pi/2]
};

// `trim`: fraction of points ignored at each end of every axis (0.02 = 2nd..98th percentile).
UprightBox fit_upright_box(const std::vector<Eigen::Vector3f>& points, double trim = 0.02);

}  // namespace kestrel::semantic
