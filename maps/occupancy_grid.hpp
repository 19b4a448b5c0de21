#pragma once
// A 2D occupancy grid in the ROS nav_msgs/OccupancyGrid convention: cell (0, 0) is the
// lower-left corner at `origin`, x grows with the column, y with the row; values are -1 for
// unknown and 0..100 for the probability of being occupied, in percent.
#include <cstdint>
#include <optional>
#include <vector>

#include "core/eigen_types.hpp"

namespace kestrel::maps {

inline constexpr std::int8_t kUnknown = -1;
inline constexpr std::int8_t kFree = 0;
inline constexpr std::int8_t kOccupied = 100;

struct GridCell {
  int x = 0;  // column
  int y = 0;  // row, counted from the bottom (world y grows with it)
  bool operator==(const GridCell&) const = default;
};

class OccupancyGrid {
 public:
  OccupancyGrid() = default;
  // Every cell starts as `fill`.
  OccupancyGrid(int width, int height, double resolution, const Vec2& origin,
                std::int8_t fill = kUnknown);

  int width() const { return width_; }
  int height() const { return height_; }
  double resolution() const { return resolution_; }  // metres per cell
  const Vec2& origin() const { return origin_; }     // world x, y of the lower-left corner
  bool empty() const { return cells_.empty(); }

  bool contains(const GridCell& c) const {
    return c.x >= 0 && c.y >= 0 && c.x < width_ && c.y < height_;
  }
  std::int8_t at(const GridCell& c) const { return cells_[index(c)]; }
  void set(const GridCell& c, std::int8_t v) { cells_[index(c)] = v; }
  std::size_t index(const GridCell& c) const {
    return static_cast<std::size_t>(c.y) * static_cast<std::size_t>(width_) +
           static_cast<std::size_t>(c.x);
  }
  const std::vector<std::int8_t>& cells() const { return cells_; }
  std::vector<std::int8_t>& cells() { return cells_; }

  // The cell holding world point (x, y); nullopt outside the grid.
  std::optional<GridCell> cell_of(const Vec2& xy) const;
  // The world point at the centre of cell c.
  Vec2 center_of(const GridCell& c) const;

  // Occupied: at or above `occupied_percent`; unknown cells count as blocked for planning.
  bool is_occupied(const GridCell& c, int occupied_percent = 65) const {
    return at(c) >= occupied_percent;
  }
  bool is_free(const GridCell& c, int free_percent = 20) const {
    const std::int8_t v = at(c);
    return v >= 0 && v < free_percent;
  }

 private:
  int width_ = 0;
  int height_ = 0;
  double resolution_ = 0.05;
  Vec2 origin_ = Vec2::Zero();
  std::vector<std::int8_t> cells_;
};

// The grid's free regions: per cell, the label of the 4-connected region of kFree cells it lies
// in, -1 for a cell that is not kFree. For A*'s 8 neighbours without corner cutting these are
// the same regions (a diagonal step needs both of its orthogonal cells open).
std::vector<int> free_regions(const OccupancyGrid& g);

}  // namespace kestrel::maps
