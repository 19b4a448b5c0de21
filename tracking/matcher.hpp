#pragma once
// Feature matching: map points projected into a frame (radius search on the frame's grid) and
// brute-force descriptor matching for relocalization and when the motion prior is lost.
#include <vector>

#include "tracking/frame_features.hpp"

namespace kestrel::tracking {

struct MatchOptions {
  int max_distance = 100;  // Hamming, of 256 bits (ORB-SLAM's TH_HIGH)
  double ratio = 0.8;      // best / second best must be below this (same pyramid level)
};

// A map point as the matcher sees it: predicted pixel, level and descriptor.
struct ProjectedPoint {
  Vec2 uv;
  int level = 0;
  OrbDescriptor descriptor;
};

// For each projected point, the index of the matched feature or -1. A feature goes to at most
// one point (the closest descriptor wins). Features with status != kStatic are never matched;
// `radius_px` is scaled by the predicted level's scale and searched on levels level-1..level+1.
std::vector<int> match_by_projection(const FrameFeatures& frame,
                                     const std::vector<ProjectedPoint>& points, double radius_px,
                                     const MatchOptions& options = {});

// For each query descriptor, the index of the best train descriptor or -1 (distance and ratio
// tests as above). Used with a few thousand descriptors at most.
std::vector<int> match_brute_force(const std::vector<OrbDescriptor>& query,
                                   const std::vector<OrbDescriptor>& train,
                                   const MatchOptions& options = {});

}  // namespace kestrel::tracking
