#pragma once
// Occupancy-grid updates as deltas: only the cells that changed since the version the receiver
// holds travel, as runs (skip, count, values) in LEB128 varints, zlib-compressed. A receiver
// whose version differs from base_seq must ask for (or wait for) a keyframe: base_seq 0.
#include <cstdint>
#include <vector>

#include "comm/schema.hpp"

namespace kestrel::comm {

// Cells row-major, one byte each (ROS map_server convention mapped to 0..100, 255 = unknown).
struct GridState {
  std::uint32_t seq = 0;
  std::uint32_t width = 0, height = 0;
  double resolution = 0.05;
  std::array<double, 2> origin{};
  std::vector<std::uint8_t> cells;
};

// Delta from `base` to `current` (same size), stamped seq = base.seq + 1 unless given. A base
// of a different size (or none: empty cells) yields a keyframe holding every cell.
GridDeltaMsg make_grid_delta(const GridState& base, const GridState& current, Timestamp t);

// Applies a delta in place. False (grid untouched) when the delta does not fit: wrong base
// version, wrong size, corrupt zlib stream or runs that run past the grid.
bool apply_grid_delta(GridState& grid, const GridDeltaMsg& delta);

}  // namespace kestrel::comm
