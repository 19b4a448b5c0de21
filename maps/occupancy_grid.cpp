#include "maps/occupancy_grid.hpp"

#include <cmath>
#include <vector>

namespace kestrel::maps {

OccupancyGrid::OccupancyGrid(int width, int height, double resolution, const Vec2& origin,
                             std::int8_t fill)
    : width_(width > 0 ? width : 0),
      height_(height > 0 ? height : 0),
      resolution_(resolution),
      origin_(origin),
      cells_(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_), fill) {}

std::optional<GridCell> OccupancyGrid::cell_of(const Vec2& xy) const {
  if (!(resolution_ > 0.0)) return std::nullopt;
  const double fx = std::floor((xy.x() - origin_.x()) / resolution_);
  const double fy = std::floor((xy.y() - origin_.y()) / resolution_);
  if (!std::isfinite(fx) || !std::isfinite(fy)) return std::nullopt;
  if (fx < 0 || fy < 0 || fx >= width_ || fy >= height_) return std::nullopt;
  return GridCell{static_cast<int>(fx), static_cast<int>(fy)};
}

Vec2 OccupancyGrid::center_of(const GridCell& c) const {
  return origin_ + Vec2((c.x + 0.5) * resolution_, (c.y + 0.5) * resolution_);
}

std::vector<int> free_regions(const OccupancyGrid& g) {
  std::vector<int> label(g.cells().size(), -1);
  const auto open = [&](const GridCell& c) {
    return g.contains(c) && g.at(c) == kFree && label[g.index(c)] < 0;
  };
  int next = 0;
  std::vector<GridCell> stack;
  for (int y = 0; y < g.height(); ++y)
    for (int x = 0; x < g.width(); ++x) {
      if (!open({x, y})) continue;
      label[g.index({x, y})] = next;
      stack.push_back({x, y});
      while (!stack.empty()) {
        const GridCell c = stack.back();
        stack.pop_back();
        const GridCell around[4] = {{c.x + 1, c.y}, {c.x - 1, c.y}, {c.x, c.y + 1}, {c.x, c.y - 1}};
        for (const GridCell& n : around)
          if (open(n)) {
            label[g.index(n)] = next;
            stack.push_back(n);
          }
      }
      ++next;
    }
  return label;
}

}  // namespace kestrel::maps
