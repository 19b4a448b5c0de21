#include "eval/pair_filter.hpp"

#include <cmath>

namespace kestrel::eval {

IdPairs filter_pairs_by_index(std::size_t count, std::size_t delta, bool all_pairs) {
  IdPairs pairs;
  if (delta == 0) return pairs;
  if (all_pairs) {
    for (std::size_t i = 0; i + delta < count; ++i) pairs.emplace_back(i, i + delta);
  } else {
    for (std::size_t i = 0; i + delta < count; i += delta) pairs.emplace_back(i, i + delta);
  }
  return pairs;
}

IdPairs filter_pairs_by_path(const std::vector<Mat4>& poses, double delta, double tol,
                             bool all_pairs) {
  IdPairs pairs;
  if (poses.empty()) return pairs;
  if (all_pairs) {
    // geometry.accumulated_distances: [0, cumsum(|p_k - p_{k+1}|)]
    std::vector<double> distances(poses.size(), 0.0);
    for (std::size_t k = 1; k < poses.size(); ++k) {
      const Vec3 step = poses[k - 1].topRightCorner<3, 1>() - poses[k].topRightCorner<3, 1>();
      distances[k] = distances[k - 1] + step.norm();
    }
    for (std::size_t i = 0; i + 1 < poses.size(); ++i) {
      std::size_t best = i + 1;
      double best_residual = std::abs((distances[i + 1] - distances[i]) - delta);
      for (std::size_t j = i + 2; j < poses.size(); ++j) {
        const double residual = std::abs((distances[j] - distances[i]) - delta);
        if (residual < best_residual) {
          best = j;
          best_residual = residual;
        }
      }
      if (best_residual > tol) continue;
      pairs.emplace_back(i, best);
    }
    return pairs;
  }
  std::vector<std::size_t> ids;
  double current_path = 0.0;
  const Mat4* previous = &poses.front();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    current_path += (poses[i].topRightCorner<3, 1>() - previous->topRightCorner<3, 1>()).norm();
    previous = &poses[i];
    if (current_path >= delta) {
      ids.push_back(i);
      current_path = 0.0;
    }
  }
  for (std::size_t k = 0; k + 1 < ids.size(); ++k) pairs.emplace_back(ids[k], ids[k + 1]);
  return pairs;
}

}  // namespace kestrel::eval
