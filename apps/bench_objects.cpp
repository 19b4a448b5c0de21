// Objects area: pipeline::run_sim_objects (ground-truth poses, ground-truth static boxes)
// scored by eval/object_metrics and eval/occupancy_metrics, per scenario; each scene runs
// twice, movers masked (what rejection gives the maps) and not masked, for the residue pair.
#include <cstdio>
#include <string>

#include "apps/bench_areas.hpp"
#include "pipeline/sim_object_run.hpp"

namespace kestrel::bench {
namespace {

std::string path_cell(const pipeline::SimObjectScores& s) {
  if (!s.path_found) return "none";
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%.1f, %s", s.path_length, s.path_clear ? "yes" : "no");
  return buf;
}

}  // namespace

nlohmann::json bench_objects(const AreaOptions& o) {
  // uav-zigzag: a drone's grid for the robots on the ground (issue 6 asks A* on every scene).
  std::vector<std::string> scenes = {"cafe", "market", "ugv-loop", "uav-zigzag"};
  if (o.quick || o.tiny) scenes = {"cafe"};
  std::printf("\n## Objects and maps (truth poses and boxes; against the world)\n\n");
  std::printf(
      "| scene | keyframes | recall | precision | centre err median (m) | size err median | "
      "class correct | grid IoU | residue, rejection | residue, off | A* path (m), clear of the "
      "world | goals in objects refused | object ms | map ms |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  nlohmann::json j;
  std::vector<std::string> detail;
  for (const std::string& scene : scenes) {
    pipeline::SimObjectRunOptions opt;
    opt.scenario = scene;
    if (o.tiny) opt.duration = 3.0;
    const pipeline::SimObjectScores s = pipeline::run_sim_objects(opt);
    opt.mask_movers = false;
    const pipeline::SimObjectScores off = pipeline::run_sim_objects(opt);
    std::printf(
        "| %s | %d | %.2f (%d/%d) | %.2f (%d reported) | %.3f | %.3f | %.2f | %.3f | "
        "%.4f | %.4f | %s | %d of %d | %.2f | %.2f |\n",
        scene.c_str(), s.keyframes, s.recall, s.matched, s.truth, s.precision, s.reported,
        s.center_error_median, s.size_error_median, s.class_correct, s.grid_iou, s.dynamic_residue,
        off.dynamic_residue, path_cell(s).c_str(), s.object_goals_refused, s.object_goals,
        s.object_ms_median, s.map_ms_median);
    j[scene] = {{"keyframes", s.keyframes},
                {"truth", s.truth},
                {"reported", s.reported},
                {"matched", s.matched},
                {"recall", s.recall},
                {"precision", s.precision},
                {"center_error_median_m", s.center_error_median},
                {"size_error_median", s.size_error_median},
                {"class_correct", s.class_correct},
                {"grid_iou", s.grid_iou},
                {"dynamic_residue_rejection", s.dynamic_residue},
                {"dynamic_residue_off", off.dynamic_residue},
                {"object_update_ms_median", s.object_ms_median},
                {"map_update_ms_median", s.map_ms_median},
                {"path_found", s.path_found},
                {"path_length_m", s.path_length},
                {"path_clear", s.path_clear},
                {"path_message", s.path_message},
                {"object_goals", s.object_goals},
                {"object_goals_refused", s.object_goals_refused}};
    detail.push_back(scene + ":");
    for (const std::string& line : s.lines) detail.push_back("  " + line);
  }
  // Each truth object's fit, so that a median can be traced to the objects behind it.
  std::printf("\n```\n");
  for (const std::string& line : detail) std::printf("%s\n", line.c_str());
  std::printf("```\n");
  return j;
}

}  // namespace kestrel::bench
