// `kestrel plan --map DIR/map.yaml --from X,Y --to X,Y [--radius R] [--out path.txt]`: A* on a
// ROS map_server grid; prints the path and writes it as "x y" lines. Flags only; the work is
// in nav/.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "apps/commands.hpp"
#include "core/error.hpp"
#include "maps/grid_io.hpp"
#include "nav/astar_planner.hpp"

namespace {

using namespace kestrel;

struct PlanArgs {
  std::string map;
  std::vector<double> from;
  std::vector<double> to;
  double radius = 0.0;
  std::string out;
  bool unknown_free = false;
};

void run_plan(const PlanArgs& a) {
  const maps::OccupancyGrid grid = maps::read_map(a.map);
  nav::PlannerOptions opt;
  opt.robot_radius = a.radius;
  opt.unknown_is_free = a.unknown_free;
  const Vec2 start(a.from[0], a.from[1]);
  const Vec2 goal(a.to[0], a.to[1]);
  const nav::PlanResult r = nav::plan_path(grid, start, goal, opt);
  if (!r.ok()) {
    std::fprintf(stderr, "kestrel plan: no path: %s\n", r.message.c_str());
    apps::exit_code() = 2;
    return;
  }
  std::printf("path: %zu waypoints, %.3f m (%zu cells expanded)\n", r.waypoints.size(), r.length,
              r.expanded);
  for (const Vec2& p : r.waypoints) std::printf("%.3f %.3f\n", p.x(), p.y());
  if (!a.out.empty()) {
    std::ofstream out(a.out);
    if (!out) throw Error::at(a.out, 0, "", "cannot write the path");
    out << "# x y [m], world frame, start to goal\n";
    char buf[64];
    for (const Vec2& p : r.waypoints) {
      std::snprintf(buf, sizeof(buf), "%.4f %.4f\n", p.x(), p.y());
      out << buf;
    }
    if (!out) throw Error::at(a.out, 0, "", "write failed");
    std::printf("wrote %s\n", a.out.c_str());
  }
}

void setup_plan(CLI::App& app) {
  auto args = std::make_shared<PlanArgs>();
  CLI::App* cmd = app.add_subcommand("plan", "A* path on an occupancy grid (ROS map_server)");
  cmd->add_option("--map", args->map, "map.yaml (with its map.pgm)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--from", args->from, "start X,Y in metres")
      ->required()
      ->expected(2)
      ->delimiter(',');
  cmd->add_option("--to", args->to, "goal X,Y in metres")->required()->expected(2)->delimiter(',');
  cmd->add_option("--radius", args->radius, "robot radius in metres (inflation)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--out", args->out, "write the path here, one 'x y' per line");
  cmd->add_flag("--unknown-free", args->unknown_free, "plan through unknown cells");
  cmd->callback([args] { run_plan(*args); });
}

}  // namespace

KESTREL_COMMAND(60, setup_plan);
