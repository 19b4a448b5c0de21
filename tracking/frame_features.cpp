#include "tracking/frame_features.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace kestrel::tracking {

void FrameFeatures::retain(const std::vector<std::uint8_t>& keep) {
  if (keep.size() != size()) {
    throw std::invalid_argument("FrameFeatures::retain: keep mask has " +
                                std::to_string(keep.size()) + " entries for " +
                                std::to_string(size()) + " features");
  }
  std::size_t out = 0;
  for (std::size_t i = 0; i < keep.size(); ++i) {
    if (!keep[i]) continue;
    keypoints[out] = keypoints[i];
    descriptors[out] = descriptors[i];
    depth[out] = depth[i];
    if (sensor_depth.size() == keep.size()) sensor_depth[out] = sensor_depth[i];
    if (on_depth_step.size() == keep.size()) on_depth_step[out] = on_depth_step[i];
    points_c[out] = points_c[i];
    status[out] = status[i];
    ++out;
  }
  keypoints.resize(out);
  descriptors.resize(out);
  depth.resize(out);
  if (sensor_depth.size() == keep.size()) sensor_depth.resize(out);
  if (on_depth_step.size() == keep.size()) on_depth_step.resize(out);
  points_c.resize(out);
  status.resize(out);
  build_grid();
}

void FrameFeatures::build_grid() {
  grid_cols = std::max(1, (width + kCellPx - 1) / kCellPx);
  grid_rows = std::max(1, (height + kCellPx - 1) / kCellPx);
  const std::size_t cells = static_cast<std::size_t>(grid_cols) * grid_rows;
  std::vector<int> cell_of(keypoints.size());
  grid_start.assign(cells + 1, 0);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const Vec2& p = keypoints[i].un;
    // Undistorted points may fall just outside the image; they go to the border cells.
    const int cx = std::clamp(static_cast<int>(std::floor(p.x() / kCellPx)), 0, grid_cols - 1);
    const int cy = std::clamp(static_cast<int>(std::floor(p.y() / kCellPx)), 0, grid_rows - 1);
    cell_of[i] = cy * grid_cols + cx;
    ++grid_start[static_cast<std::size_t>(cell_of[i]) + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) grid_start[c + 1] += grid_start[c];
  grid_index.resize(keypoints.size());
  std::vector<int> next(grid_start.begin(), grid_start.end() - 1);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    grid_index[static_cast<std::size_t>(next[static_cast<std::size_t>(cell_of[i])]++)] =
        static_cast<int>(i);
  }
}

std::vector<int> FrameFeatures::in_radius(double u, double v, double radius, int min_level,
                                          int max_level) const {
  std::vector<int> out;
  if (grid_start.empty() || !std::isfinite(u) || !std::isfinite(v)) return out;
  const int x0 = std::max(0, static_cast<int>(std::floor((u - radius) / kCellPx)));
  const int x1 = std::min(grid_cols - 1, static_cast<int>(std::floor((u + radius) / kCellPx)));
  const int y0 = std::max(0, static_cast<int>(std::floor((v - radius) / kCellPx)));
  const int y1 = std::min(grid_rows - 1, static_cast<int>(std::floor((v + radius) / kCellPx)));
  const double r2 = radius * radius;
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      const std::size_t c = static_cast<std::size_t>(cy) * grid_cols + cx;
      for (int j = grid_start[c]; j < grid_start[c + 1]; ++j) {
        const int i = grid_index[static_cast<std::size_t>(j)];
        const Keypoint& k = keypoints[static_cast<std::size_t>(i)];
        if (min_level >= 0 && k.level < min_level) continue;
        if (max_level >= 0 && k.level > max_level) continue;
        if ((k.un - Vec2(u, v)).squaredNorm() <= r2) out.push_back(i);
      }
    }
  }
  return out;
}

}  // namespace kestrel::tracking
