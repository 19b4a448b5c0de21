#include "pipeline/sim_object_run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "eval/object_metrics.hpp"
#include "eval/occupancy_metrics.hpp"
#include "nav/astar_planner.hpp"
#include "nav/inflation.hpp"
#include "sim/simulator.hpp"

namespace kestrel::pipeline {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The grid's frame and cells as eval/'s plain rasters.
eval::GridFrame frame_of(const maps::OccupancyGrid& g) {
  return {g.width(), g.height(), g.resolution(), g.origin()};
}

// Occupied cells of the static scene (scenery and objects) in the grid's height band.
eval::CellMask truth_occupancy(const sim::World& world, const maps::OccupancyGrid& g, double z_min,
                               double z_max) {
  std::vector<eval::WorldTriangle> tris;
  tris.reserve(world.static_mesh().size());
  for (const sim::Triangle& t : world.static_mesh())
    tris.push_back({t.v[0].p.cast<double>(), t.v[1].p.cast<double>(), t.v[2].p.cast<double>()});
  return eval::rasterize_triangles(tris, frame_of(g), z_min, z_max);
}

eval::ObjectBox box_of(const std::string& label, const Vec3& center, const Vec3& size, double yaw,
                       int observations) {
  return {label, center, size, yaw, observations};
}

// Issue 6's planning check on the built grid: a path between two places the camera passed that
// lie in one free region the robot fits in (a drone's grid is a patchwork of what it looked at,
// and a handheld camera's of what it faced), clear of the world's static geometry; and no path
// into any object.
void plan_on_grid(const maps::OccupancyGrid& g, const eval::CellMask& truth_cells,
                  const std::vector<Vec2>& places,
                  const std::vector<const sim::StaticObject*>& objects, double radius,
                  SimObjectScores& s) {
  nav::PlannerOptions po;
  po.robot_radius = radius;
  const maps::OccupancyGrid inflated = nav::inflate(g, radius);
  const std::vector<int> region = maps::free_regions(inflated);
  std::map<int, std::vector<Vec2>> by_region;
  for (const Vec2& p : places)
    if (const auto c = inflated.cell_of(p); c && region[inflated.index(*c)] >= 0)
      by_region[region[inflated.index(*c)]].push_back(p);
  std::vector<Vec2> free;
  for (const auto& [id, ps] : by_region)
    if (ps.size() > free.size()) free = ps;
  double best = -1.0;
  Vec2 from = Vec2::Zero(), to = Vec2::Zero();
  for (std::size_t i = 0; i < free.size(); ++i)
    for (std::size_t j = i + 1; j < free.size(); ++j)
      if ((free[i] - free[j]).norm() > best) {
        best = (free[i] - free[j]).norm();
        from = free[i];
        to = free[j];
      }
  if (best < 0) {
    s.path_message = "no keyframe place is free in the inflated grid";
    return;
  }
  const nav::PlanResult r = nav::plan_path(g, from, to, po);
  s.path_found = r.ok();
  s.path_message = r.message;
  if (r.ok()) {
    s.path_length = r.length;
    s.path_clear = std::none_of(r.cells.begin(), r.cells.end(),
                                [&](const maps::GridCell& c) { return truth_cells.at(c.x, c.y); });
  }
  for (const sim::StaticObject* w : objects) {
    ++s.object_goals;
    const nav::PlanResult into = nav::plan_path(g, from, w->center.head<2>(), po);
    if (into.status == nav::PlanStatus::kGoalBlocked) {
      ++s.object_goals_refused;
      if (s.object_goal_message.empty()) s.object_goal_message = w->label + ": " + into.message;
    }
  }
}

}  // namespace

SimObjectScores run_sim_objects(const SimObjectRunOptions& o) {
  sim::ScenarioOverrides ov;
  ov.duration = o.duration;
  sim::Scenario scenario = sim::load_scenario(o.scenario, ov);
  if (o.edit_scenario) o.edit_scenario(scenario);
  sim::Simulator sim(std::move(scenario));
  const Calibration& calib = sim.calibration();
  semantic::ObjectDatabase db;
  maps::MapBuilder maps_builder(maps::map_builder_options(calib.depth_max));
  std::vector<double> obj_ms, map_ms;
  std::map<int, int> given;  // world object id -> keyframes it was given as a detection
  const int min_pixels = 400;
  SimObjectScores s;
  const bool ground_robot = sim.scenario().trajectory.kind == "ugv" && o.robot_radius > 0.0;
  std::vector<Vec2> places;  // the keyframes' body positions, for the planning check
  for (int k = 0; k < sim.frame_count(); k += o.keyframe_every) {
    const sim::SimFrame f = sim.render(k);
    const SE3 T_w_c = sim.camera_pose(f.time);
    places.push_back((T_w_c * calib.T_body_camera.inverse()).translation().head<2>());
    // Mover ids whose pixels are masked: all, or only people and movers that move now.
    std::vector<bool> masked_id(sim.world().movers().size() + 1, true);
    masked_id[0] = false;
    if (o.detect_still_movers)
      for (const sim::SimBox& b : f.boxes)
        if (b.instance < sim::kFirstObjectId && (!b.moving || !o.moving_flags) &&
            b.label != "person")
          masked_id[static_cast<std::size_t>(b.instance)] = false;
    std::vector<std::uint8_t> static_mask(static_cast<std::size_t>(f.mask.width) * f.mask.height);
    for (int v = 0; v < f.mask.height; ++v)
      for (int u = 0; u < f.mask.width; ++u) {
        const std::uint16_t id = f.mask.row<std::uint16_t>(v)[u];
        static_mask[static_cast<std::size_t>(v) * f.mask.width + u] =
            id >= masked_id.size() || !masked_id[id];
      }
    semantic::ObjectKeyframe kf;
    kf.keyframe_id = k;
    kf.T_w_c = T_w_c;
    kf.stamp = f.stamp;
    kf.depth = &f.depth;
    kf.depth_scale = calib.depth_scale;
    kf.camera = calib.camera;
    kf.static_mask = o.mask_movers ? &static_mask : nullptr;
    for (const sim::SimBox& b : f.boxes) {
      detect::Detection d;
      d.label = b.label;
      d.score = 0.9f;
      d.x_min = static_cast<float>(b.x_min);
      d.y_min = static_cast<float>(b.y_min);
      d.x_max = static_cast<float>(b.x_max);
      d.y_max = static_cast<float>(b.y_max);
      if (b.instance >= sim::kFirstObjectId) {
        if (b.pixels < min_pixels || b.occluded > 0.5) continue;
        kf.static_boxes.push_back(d);
        // Truth counts objects the sensor can range: within its depth limit.
        const sim::StaticObject& w =
            sim.world().objects()[static_cast<std::size_t>(b.instance - sim::kFirstObjectId)];
        if ((w.center - T_w_c.translation()).norm() < sim.scenario().sensor.depth_max - 0.5)
          ++given[b.instance];
      } else if (b.moving && o.moving_flags && b.label != "person") {
        kf.moving_boxes.push_back(d);
      } else if (o.detect_still_movers && b.label != "person" && b.pixels >= min_pixels &&
                 b.occluded <= 0.5) {
        kf.static_boxes.push_back(d);
      }
    }
    auto t0 = std::chrono::steady_clock::now();
    db.update(kf);
    obj_ms.push_back(ms_since(t0));
    if (o.on_keyframe) o.on_keyframe(sim, f.time, db);
    if (o.build_maps) {
      maps::MapKeyframe mk;
      mk.T_w_c = T_w_c;
      mk.color = &f.color;
      mk.depth = &f.depth;
      mk.depth_scale = calib.depth_scale;
      mk.camera = calib.camera;
      mk.static_mask = o.mask_movers ? &static_mask : nullptr;
      if (ground_robot)
        mk.footprint = maps::Footprint{
            (T_w_c * calib.T_body_camera.inverse()).translation().head<2>(), o.robot_radius};
      t0 = std::chrono::steady_clock::now();
      maps_builder.insert(mk);
      map_ms.push_back(ms_since(t0));
    }
    ++s.keyframes;
  }
  s.object_ms_median = median(obj_ms);
  s.map_ms_median = median(map_ms);

  const auto reported = db.objects();
  s.reported = static_cast<int>(reported.size());
  std::vector<const sim::StaticObject*> truth;
  for (const sim::StaticObject& w : sim.world().objects())
    if (given[w.id] >= 3) truth.push_back(&w);
  s.truth = static_cast<int>(truth.size());
  std::vector<eval::ObjectBox> truth_boxes, reported_boxes;
  for (const sim::StaticObject* w : truth)
    truth_boxes.push_back(box_of(w->label, w->center, w->size, w->yaw, 0));
  for (const semantic::SemanticObject& r : reported)
    reported_boxes.push_back(box_of(r.label, r.box.center, r.box.size, r.box.yaw, r.observations));
  const eval::ObjectScores scores = eval::score_objects(truth_boxes, reported_boxes);
  s.matched = scores.matched;
  s.label_correct = scores.label_correct;
  s.recall = scores.recall;
  s.precision = scores.precision;
  s.class_correct = scores.class_correct;
  s.center_error_median = scores.center_error_median;
  s.size_error_median = scores.size_error_median;
  s.lines = scores.lines;
  if (o.build_maps) {
    const maps::OccupancyGrid& g = maps_builder.grid();
    const double z_min = maps_builder.options().grid_z_min,
                 z_max = maps_builder.options().grid_z_max;
    const eval::CellMask truth_cells = truth_occupancy(sim.world(), g, z_min, z_max);
    eval::CellMask est(frame_of(g)), known(frame_of(g));
    for (std::size_t i = 0; i < g.cells().size(); ++i) {
      est.cells[i] = g.cells()[i] == maps::kOccupied;
      known.cells[i] = g.cells()[i] != maps::kUnknown;
    }
    // Only where the map has looked: unseen walls are not the map's fault.
    s.grid_iou = g.empty() ? 0.0 : eval::occupancy_iou(est, known, truth_cells);
    std::vector<std::vector<Vec2>> paths;
    for (const sim::MoverSpec& m : sim.world().movers()) {
      paths.emplace_back();
      for (const Vec3& p : m.path) paths.back().push_back(p.head<2>());
    }
    plan_on_grid(g, truth_cells, places, truth, o.robot_radius, s);
    // Within 0.5 m of a walker's path: about a person's reach and stride.
    s.dynamic_residue = g.empty() ? 0.0
                                  : eval::dynamic_residue(maps_builder.octree().occupied_voxels(),
                                                          truth_cells, paths, 0.5, z_min, z_max);
  }
  if (!o.out_dir.empty()) {
    db.write_outputs(o.out_dir);
    if (o.build_maps) maps_builder.write_outputs(o.out_dir);
  }
  return s;
}

}  // namespace kestrel::pipeline
