#pragma once
#include <vector>

#include "core/se3.hpp"

namespace kestrel {

// A sequence of stamped poses T_w_body. Stamps stay in seconds as double because the
// reference tools (evo, the TUM benchmark scripts) associate and compare them in double;
// matching their numbers exactly means doing the same arithmetic.
struct Trajectory {
  std::vector<double> stamps;
  std::vector<SE3> poses;

  std::size_t size() const { return poses.size(); }
  bool empty() const { return poses.empty(); }
  void push_back(double stamp, const SE3& pose) {
    stamps.push_back(stamp);
    poses.push_back(pose);
  }
};

}  // namespace kestrel
