#pragma once
// A* on an occupancy grid, 8-connected, with the octile distance as heuristic. Diagonal moves
// may not cut the corner of a blocked cell. Unknown cells are blocked: a robot should not drive
// where it has never seen.
#include <string>
#include <vector>

#include "maps/occupancy_grid.hpp"

namespace kestrel::nav {

enum class PlanStatus {
  kOk,
  kStartOutside,
  kGoalOutside,
  kStartBlocked,
  kGoalBlocked,
  kUnreachable,
};

struct PlanResult {
  PlanStatus status = PlanStatus::kUnreachable;
  std::string message;                // why no path, in words a user can act on
  std::vector<maps::GridCell> cells;  // start to goal, both included
  std::vector<Vec2> waypoints;        // cell centres, world frame
  double length = 0.0;                // metres along the waypoints
  std::size_t expanded = 0;           // cells taken off the open list
  bool ok() const { return status == PlanStatus::kOk; }
};

struct PlannerOptions {
  double robot_radius = 0.0;  // metres; the grid is inflated by it before planning
  int occupied_percent = 65;  // a cell at or above it is an obstacle
  bool unknown_is_free = false;
};

// Plans on `grid` (inflated by options.robot_radius) from start to goal, world x, y.
PlanResult plan_path(const maps::OccupancyGrid& grid, const Vec2& start, const Vec2& goal,
                     const PlannerOptions& options = {});

}  // namespace kestrel::nav
