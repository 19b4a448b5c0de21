#include "eval/occupancy_metrics.hpp"

#include <algorithm>
#include <cmath>

namespace kestrel::eval {

std::optional<std::array<int, 2>> GridFrame::cell_of(const Vec2& xy) const {
  if (!(resolution > 0.0)) return std::nullopt;
  const double fx = std::floor((xy.x() - origin.x()) / resolution);
  const double fy = std::floor((xy.y() - origin.y()) / resolution);
  if (!std::isfinite(fx) || !std::isfinite(fy)) return std::nullopt;
  if (fx < 0 || fy < 0 || fx >= width || fy >= height) return std::nullopt;
  return std::array<int, 2>{static_cast<int>(fx), static_cast<int>(fy)};
}

bool CellMask::at(int x, int y) const {
  return x >= 0 && y >= 0 && x < frame.width && y < frame.height && cells[frame.index(x, y)];
}

bool CellMask::near(int x, int y) const {
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      if (at(x + dx, y + dy)) return true;
  return false;
}

CellMask rasterize_triangles(const std::vector<WorldTriangle>& triangles, const GridFrame& frame,
                             double z_min, double z_max) {
  CellMask occ(frame);
  const double step = frame.resolution / 3;
  if (!(step > 0.0)) return occ;
  for (const WorldTriangle& t : triangles) {
    const Vec3 &a = t[0], &b = t[1], &c = t[2];
    const int n =
        std::max(1, static_cast<int>(std::ceil(std::max((b - a).norm(), (c - a).norm()) / step)));
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const Vec3 p = a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n);
        if (p.z() < z_min || p.z() > z_max) continue;
        if (const auto cell = frame.cell_of(p.head<2>()))
          occ.cells[frame.index((*cell)[0], (*cell)[1])] = 1;
      }
  }
  return occ;
}

double occupancy_iou(const CellMask& est, const CellMask& known, const CellMask& truth) {
  const GridFrame& g = est.frame;
  if (g.width <= 0 || g.height <= 0) return 0.0;
  int tp = 0, fp = 0, fn = 0;
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x) {
      if (est.at(x, y))
        (truth.near(x, y) ? tp : fp)++;
      else if (truth.at(x, y) && known.near(x, y) && !est.near(x, y))
        ++fn;
    }
  return tp + fp + fn > 0 ? static_cast<double>(tp) / (tp + fp + fn) : 0.0;
}

double dynamic_residue(const std::vector<Vec3>& voxels, const CellMask& truth,
                       const std::vector<std::vector<Vec2>>& paths, double radius, double z_min,
                       double z_max) {
  auto near_path = [&](const Vec2& p) {
    for (const std::vector<Vec2>& path : paths)
      for (std::size_t i = 0; i < path.size(); ++i) {
        // Segment i .. i+1; a one-point path is a point.
        const Vec2 a = path[i], b = path[std::min(i + 1, path.size() - 1)];
        const Vec2 ab = b - a;
        const double t =
            ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
        if ((a + t * ab - p).norm() < radius) return true;
        if (i + 2 >= path.size()) break;
      }
    return false;
  };
  int total = 0, residue = 0;
  for (const Vec3& v : voxels) {
    if (v.z() < z_min || v.z() > z_max) continue;
    ++total;
    const auto c = truth.frame.cell_of(v.head<2>());
    if (c && !truth.near((*c)[0], (*c)[1]) && near_path(v.head<2>())) ++residue;
  }
  return total > 0 ? static_cast<double>(residue) / total : 0.0;
}

}  // namespace kestrel::eval
