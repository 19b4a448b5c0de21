#include "tracking/matcher.hpp"

#include <limits>

namespace kestrel::tracking {

std::vector<int> match_by_projection(const FrameFeatures& frame,
                                     const std::vector<ProjectedPoint>& points, double radius_px,
                                     const MatchOptions& options) {
  std::vector<int> match(points.size(), -1);
  std::vector<int> owner(frame.size(), -1);
  std::vector<int> owner_dist(frame.size(), std::numeric_limits<int>::max());
  for (std::size_t p = 0; p < points.size(); ++p) {
    const ProjectedPoint& pt = points[p];
    const double r = radius_px * frame.level_scale(pt.level);
    const std::vector<int> cands =
        frame.in_radius(pt.uv.x(), pt.uv.y(), r, std::max(0, pt.level - 1), pt.level + 1);
    int best = std::numeric_limits<int>::max(), second = best;
    int best_level = -1, second_level = -1, best_idx = -1;
    for (int i : cands) {
      const auto ui = static_cast<std::size_t>(i);
      if (frame.status[ui] != FeatureStatus::kStatic) continue;
      const int d = hamming(pt.descriptor, frame.descriptors[ui]);
      if (d < best) {
        second = best;
        second_level = best_level;
        best = d;
        best_level = frame.keypoints[ui].level;
        best_idx = i;
      } else if (d < second) {
        second = d;
        second_level = frame.keypoints[ui].level;
      }
    }
    if (best_idx < 0 || best > options.max_distance) continue;
    // An ambiguous best on the same level is likely repeated texture: skip it.
    if (best_level == second_level && best > options.ratio * second) continue;
    const auto ub = static_cast<std::size_t>(best_idx);
    if (best >= owner_dist[ub]) continue;
    if (owner[ub] >= 0) match[static_cast<std::size_t>(owner[ub])] = -1;
    owner[ub] = static_cast<int>(p);
    owner_dist[ub] = best;
    match[p] = best_idx;
  }
  return match;
}

std::vector<int> match_brute_force(const std::vector<OrbDescriptor>& query,
                                   const std::vector<OrbDescriptor>& train,
                                   const MatchOptions& options) {
  std::vector<int> match(query.size(), -1);
  std::vector<int> owner(train.size(), -1);
  std::vector<int> owner_dist(train.size(), std::numeric_limits<int>::max());
  for (std::size_t q = 0; q < query.size(); ++q) {
    int best = std::numeric_limits<int>::max(), second = best, best_idx = -1;
    for (std::size_t t = 0; t < train.size(); ++t) {
      const int d = hamming(query[q], train[t]);
      if (d < best) {
        second = best;
        best = d;
        best_idx = static_cast<int>(t);
      } else if (d < second) {
        second = d;
      }
    }
    if (best_idx < 0 || best > options.max_distance || best > options.ratio * second) continue;
    const auto ub = static_cast<std::size_t>(best_idx);
    if (best >= owner_dist[ub]) continue;
    if (owner[ub] >= 0) match[static_cast<std::size_t>(owner[ub])] = -1;
    owner[ub] = static_cast<int>(q);
    owner_dist[ub] = best;
    match[q] = best_idx;
  }
  return match;
}

}  // namespace kestrel::tracking
