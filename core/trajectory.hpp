#pragma once
#include <algorithm>
#include <cmath>
#include <optional>
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

// Index of the pose whose stamp is nearest t (the earlier one on a tie), when it lies within
// max_diff seconds; stamps sorted.
inline std::optional<std::size_t> nearest_pose(const Trajectory& tr, double t, double max_diff) {
  if (tr.empty()) return std::nullopt;
  const auto& st = tr.stamps;
  const auto it = std::lower_bound(st.begin(), st.end(), t);
  std::size_t i = it == st.end() ? st.size() - 1 : static_cast<std::size_t>(it - st.begin());
  if (i > 0 && std::fabs(st[i - 1] - t) < std::fabs(st[i] - t)) --i;
  if (std::fabs(st[i] - t) > max_diff) return std::nullopt;
  return i;
}

}  // namespace kestrel
