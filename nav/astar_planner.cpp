#include "nav/astar_planner.hpp"

#include "nav/inflation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <queue>

namespace kestrel::nav {
namespace {

std::string xy(const Vec2& p) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "(%.3f, %.3f)", p.x(), p.y());
  return buf;
}

PlanResult fail(PlanStatus s, std::string message) {
  PlanResult r;
  r.status = s;
  r.message = std::move(message);
  return r;
}

}  // namespace

PlanResult plan_path(const maps::OccupancyGrid& raw, const Vec2& start, const Vec2& goal,
                     const PlannerOptions& options) {
  const maps::OccupancyGrid grid = inflate(raw, options.robot_radius);
  const auto s = grid.cell_of(start);
  if (!s) return fail(PlanStatus::kStartOutside, "start " + xy(start) + " is outside the map");
  const auto g = grid.cell_of(goal);
  if (!g) return fail(PlanStatus::kGoalOutside, "goal " + xy(goal) + " is outside the map");
  auto blocked = [&](const maps::GridCell& c) {
    const std::int8_t v = grid.at(c);
    if (v < 0) return !options.unknown_is_free;
    return v >= options.occupied_percent;
  };
  auto why = [&](const maps::GridCell& c) -> std::string {
    if (raw.at(c) < 0) return "in unknown space";
    if (raw.at(c) >= options.occupied_percent) return "inside an obstacle";
    return "closer than the robot radius to an obstacle";
  };
  if (blocked(*s)) return fail(PlanStatus::kStartBlocked, "start " + xy(start) + " is " + why(*s));
  if (blocked(*g)) return fail(PlanStatus::kGoalBlocked, "goal " + xy(goal) + " is " + why(*g));

  const std::size_t n = grid.cells().size();
  std::vector<double> cost(n, std::numeric_limits<double>::infinity());
  std::vector<std::int32_t> parent(n, -1);
  std::vector<bool> closed(n, false);
  auto h = [&](const maps::GridCell& c) {
    const double dx = std::abs(c.x - g->x), dy = std::abs(c.y - g->y);
    return (dx + dy) + (std::sqrt(2.0) - 2.0) * std::min(dx, dy);
  };
  using Entry = std::pair<double, std::int32_t>;  // f, index
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
  const auto si = static_cast<std::int32_t>(grid.index(*s));
  const auto gi = static_cast<std::int32_t>(grid.index(*g));
  cost[si] = 0.0;
  open.push({h(*s), si});
  PlanResult r;
  while (!open.empty()) {
    const auto [f, i] = open.top();
    open.pop();
    if (closed[i]) continue;
    closed[i] = true;
    ++r.expanded;
    if (i == gi) break;
    const maps::GridCell c{i % grid.width(), i / grid.width()};
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const maps::GridCell nb{c.x + dx, c.y + dy};
        if (!grid.contains(nb) || blocked(nb)) continue;
        // No corner cutting: both orthogonal neighbours of a diagonal step must be open.
        if (dx != 0 && dy != 0 && (blocked({c.x + dx, c.y}) || blocked({c.x, c.y + dy}))) continue;
        const auto ni = static_cast<std::int32_t>(grid.index(nb));
        if (closed[ni]) continue;
        const double step = (dx != 0 && dy != 0) ? std::sqrt(2.0) : 1.0;
        const double nc = cost[i] + step;
        if (nc < cost[ni]) {
          cost[ni] = nc;
          parent[ni] = i;
          open.push({nc + h(nb), ni});
        }
      }
    }
  }
  if (!closed[gi]) {
    PlanResult u =
        fail(PlanStatus::kUnreachable, "goal " + xy(goal) + " cannot be reached from start " +
                                           xy(start) + " (no free path on the inflated map)");
    u.expanded = r.expanded;
    return u;
  }
  for (std::int32_t i = gi; i >= 0; i = parent[i])
    r.cells.push_back({i % grid.width(), i / grid.width()});
  std::reverse(r.cells.begin(), r.cells.end());
  for (const maps::GridCell& c : r.cells) r.waypoints.push_back(grid.center_of(c));
  for (std::size_t k = 1; k < r.waypoints.size(); ++k)
    r.length += (r.waypoints[k] - r.waypoints[k - 1]).norm();
  r.status = PlanStatus::kOk;
  return r;
}

}  // namespace kestrel::nav
