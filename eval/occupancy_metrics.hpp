#pragma once
// Map accuracy against a simulated world: the static geometry rasterized into the grid's
// cells, IoU of occupied cells, and the dynamic residue (what movers left in the 3D map).
// Plain rasters and points, so eval/ needs neither maps/ nor sim/; callers copy their grid's
// frame and cells in.
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "core/eigen_types.hpp"

namespace kestrel::eval {

// A 2D grid's geometry: cell (x, y) covers origin + [x, x+1) * resolution (rows from the
// bottom), as maps::OccupancyGrid lays its cells out.
struct GridFrame {
  int width = 0;
  int height = 0;
  double resolution = 0.0;
  Vec2 origin = Vec2::Zero();
  std::optional<std::array<int, 2>> cell_of(const Vec2& xy) const;
  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
           static_cast<std::size_t>(x);
  }
};

// One flag per cell of a GridFrame, row-major from the bottom row.
struct CellMask {
  GridFrame frame;
  std::vector<std::uint8_t> cells;
  explicit CellMask(const GridFrame& f = {})
      : frame(f), cells(static_cast<std::size_t>(f.width) * f.height, 0) {}
  bool at(int x, int y) const;    // false outside
  bool near(int x, int y) const;  // any of the 3x3 cells around (x, y)
};

using WorldTriangle = std::array<Vec3, 3>;

// Cells touched by the triangles' parts within [z_min, z_max], sampled at a third of a cell.
CellMask rasterize_triangles(const std::vector<WorldTriangle>& triangles, const GridFrame& frame,
                             double z_min, double z_max);

// IoU of occupied cells with one cell of slack, only where the map has looked: an estimated
// cell next to a truth cell is a hit, else a false alarm; a truth cell next to a known cell
// and with no estimated cell near is a miss. 0 for an empty frame.
double occupancy_iou(const CellMask& estimated, const CellMask& known, const CellMask& truth);

// Occupied voxels within `radius` (horizontally) of a mover's path and not next to static
// geometry, as a fraction of all occupied voxels in [z_min, z_max].
double dynamic_residue(const std::vector<Vec3>& occupied_voxels, const CellMask& truth,
                       const std::vector<std::vector<Vec2>>& mover_paths, double radius,
                       double z_min, double z_max);

}  // namespace kestrel::eval
