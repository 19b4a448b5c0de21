#pragma once
#include "maps/occupancy_grid.hpp"

namespace kestrel::nav {

// A copy where every cell within `radius` metres of an occupied cell is occupied too: a
// circular robot of that radius may then be planned as a point.
maps::OccupancyGrid inflate(const maps::OccupancyGrid& grid, double radius);

}  // namespace kestrel::nav
