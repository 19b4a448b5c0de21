#include "nav/inflation.hpp"

#include <cmath>
#include <vector>

namespace kestrel::nav {

maps::OccupancyGrid inflate(const maps::OccupancyGrid& grid, double radius) {
  maps::OccupancyGrid out = grid;
  if (!(radius > 0.0) || grid.empty()) return out;
  const int r = static_cast<int>(std::ceil(radius / grid.resolution()));
  // Disc offsets once; cells whose centres lie within the radius of the obstacle's centre.
  std::vector<maps::GridCell> disc;
  const double r_cells = radius / grid.resolution();
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      if (dx * dx + dy * dy <= r_cells * r_cells + 1e-9) disc.push_back({dx, dy});
  for (int y = 0; y < grid.height(); ++y) {
    for (int x = 0; x < grid.width(); ++x) {
      if (!grid.is_occupied({x, y})) continue;
      // Interior cells of a blob need no disc of their own: their neighbours carry it.
      bool interior = true;
      for (int k = 0; k < 4 && interior; ++k) {
        const maps::GridCell n{x + (k == 0) - (k == 1), y + (k == 2) - (k == 3)};
        interior = grid.contains(n) && grid.is_occupied(n);
      }
      if (interior) continue;
      for (const maps::GridCell& d : disc) {
        const maps::GridCell c{x + d.x, y + d.y};
        if (out.contains(c) && out.at(c) < maps::kOccupied) out.set(c, maps::kOccupied);
      }
    }
  }
  return out;
}

}  // namespace kestrel::nav
