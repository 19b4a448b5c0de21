#pragma once
// The features of one frame: keypoints (raw and undistorted), ORB descriptors, depth-based 3D
// points and per-feature status. Plain data with a spatial grid for radius search; no OpenCV.
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/eigen_types.hpp"
#include "core/timestamp.hpp"
#include "tracking/orb_descriptor.hpp"

namespace kestrel::tracking {

// What the dynamic filter decided about a feature. Features start static: only evidence of
// motion demotes them.
enum class FeatureStatus : std::uint8_t { kStatic, kDynamic, kUnknown };

struct Keypoint {
  Vec2 px;             // as detected, in the (distorted) image
  Vec2 un;             // undistorted, in pixels of the ideal pinhole with the same K
  float angle = 0.0f;  // orientation in degrees, as cv::KeyPoint
  float response = 0.0f;
  int level = 0;  // pyramid level (octave)
};

struct FrameFeatures {
  Timestamp t = 0;
  int width = 0;
  int height = 0;
  float scale_factor = 1.2f;  // between pyramid levels
  int levels = 8;

  std::vector<Keypoint> keypoints;
  std::vector<OrbDescriptor> descriptors;
  // Depth in metres at the keypoint, 0 where there is none (hole, out of range, monocular).
  std::vector<double> depth;
  // The sensor's reading under the keypoint (0: none or out of range) even where `depth` is 0
  // because the keypoint sits on a depth step: the dynamic filter wants it there (movers'
  // silhouettes are where their features are), map points must not be seeded from it. May be
  // empty: the System hands it to the filter, and keyframes do not keep it.
  std::vector<double> sensor_depth;
  // 1 where the keypoint has no depth but the sensor has readings at or around it: it sits on a
  // depth step or a hole at an object's outline (sensors leave those), not beyond the sensor's
  // range. Its patch spans a foreground edge and what lies behind it, which move apart as the
  // camera moves: no fixed 3D point to triangulate. Empty when depth did not come from a range
  // sensor's image (stereo, monocular), and in keyframes loaded from map.bin (not saved: a
  // loaded keyframe paired with a new one is triangulated without the outline and range checks
  // on its side).
  std::vector<std::uint8_t> on_depth_step;
  // Camera-frame point from depth (meaningful only where depth > 0).
  std::vector<Vec3> points_c;
  std::vector<FeatureStatus> status;

  std::size_t size() const { return keypoints.size(); }
  bool has_depth(std::size_t i) const { return depth[i] > 0.0; }
  bool is_on_depth_step(std::size_t i) const {
    return i < on_depth_step.size() && on_depth_step[i] != 0;
  }

  // Scale of a pyramid level relative to level 0, and its squared value (the variance of a
  // keypoint position in level-0 pixels grows with it).
  // Inline because mapping/ uses it without linking the tracking library. The values of std::pow
  // from a per-thread table: pow on every call was a tenth of the local-mapping thread's time
  // (triangulation asks for every candidate pair's levels).
  double level_scale(int level) const {
    constexpr int kLevels = 32;
    thread_local bool filled = false;
    thread_local float table_factor = 0.0f;
    thread_local std::array<double, kLevels> table{};
    if (level < 0 || level >= kLevels) return std::pow(static_cast<double>(scale_factor), level);
    if (!filled || scale_factor != table_factor) {
      for (int l = 0; l < kLevels; ++l) table[l] = std::pow(static_cast<double>(scale_factor), l);
      table_factor = scale_factor;
      filled = true;
    }
    return table[level];
  }
  double level_sigma2(int level) const { return level_scale(level) * level_scale(level); }

  // Keeps the features whose keep[i] != 0 (all per-feature arrays stay aligned) and rebuilds
  // the grid. keep.size() must equal size().
  void retain(const std::vector<std::uint8_t>& keep);

  // Indices of features whose undistorted position lies within `radius` pixels of (u, v) and
  // whose level is within [min_level, max_level] (-1: no bound). Needs build_grid().
  std::vector<int> in_radius(double u, double v, double radius, int min_level = -1,
                             int max_level = -1) const;
  void build_grid();

  static constexpr int kCellPx = 16;
  int grid_cols = 0;
  int grid_rows = 0;
  // The features of grid cell c are grid_index[grid_start[c] .. grid_start[c + 1]), in index
  // order: two flat arrays rather than a vector per cell, because every keyframe keeps its grid
  // (a vector per cell cost ~34 KB a keyframe, mostly empty headers, and ~700 allocations).
  std::vector<int> grid_start;
  std::vector<int> grid_index;
};

}  // namespace kestrel::tracking
