#include "tests/semantic/sim_object_run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "sim/simulator.hpp"

namespace kestrel::test {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Occupied cells of the static scene (scenery and objects) in the grid's height band.
std::vector<std::uint8_t> truth_occupancy(const sim::World& world, const maps::OccupancyGrid& g,
                                          double z_min, double z_max) {
  std::vector<std::uint8_t> occ(g.cells().size(), 0);
  const double step = g.resolution() / 3;
  for (const sim::Triangle& t : world.static_mesh()) {
    const Vec3 a = t.v[0].p.cast<double>(), b = t.v[1].p.cast<double>(),
               c = t.v[2].p.cast<double>();
    const int n =
        std::max(1, static_cast<int>(std::ceil(std::max((b - a).norm(), (c - a).norm()) / step)));
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const Vec3 p = a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n);
        if (p.z() < z_min || p.z() > z_max) continue;
        if (const auto cell = g.cell_of(p.head<2>())) occ[g.index(*cell)] = 1;
      }
  }
  return occ;
}

bool near_any(const maps::OccupancyGrid& g, const std::vector<std::uint8_t>& m,
              const maps::GridCell& c) {
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const maps::GridCell n{c.x + dx, c.y + dy};
      if (g.contains(n) && m[g.index(n)]) return true;
    }
  return false;
}

double grid_iou(const sim::World& world, const maps::OccupancyGrid& g, double z_min, double z_max) {
  if (g.empty()) return 0.0;
  const auto truth = truth_occupancy(world, g, z_min, z_max);
  std::vector<std::uint8_t> est(g.cells().size(), 0), known(g.cells().size(), 0);
  for (std::size_t i = 0; i < est.size(); ++i) {
    est[i] = g.cells()[i] == maps::kOccupied;
    known[i] = g.cells()[i] != maps::kUnknown;
  }
  // Only where the map has looked: unseen walls are not the map's fault.
  int tp = 0, fp = 0, fn = 0;
  for (int y = 0; y < g.height(); ++y)
    for (int x = 0; x < g.width(); ++x) {
      const maps::GridCell c{x, y};
      const std::size_t i = g.index(c);
      if (est[i])
        (near_any(g, truth, c) ? tp : fp)++;
      else if (truth[i] && near_any(g, known, c) && !near_any(g, est, c))
        ++fn;
    }
  return tp + fp + fn > 0 ? static_cast<double>(tp) / (tp + fp + fn) : 0.0;
}

// Occupied voxels (grid band) within 0.5 m of a mover's path and not next to static geometry,
// as a fraction of all occupied voxels in the band: what walkers left in the map.
double dynamic_residue(const sim::World& world, const maps::OccupancyOctree& octree,
                       const maps::OccupancyGrid& g, double z_min, double z_max) {
  if (g.empty()) return 0.0;
  const auto truth = truth_occupancy(world, g, z_min, z_max);
  auto near_path = [&](const Vec3& p) {
    for (const sim::MoverSpec& m : world.movers())
      for (std::size_t i = 0; i + 1 < m.path.size() || (i == 0 && m.path.size() == 1); ++i) {
        const Vec2 a = m.path[i].head<2>();
        const Vec2 b = m.path[std::min(i + 1, m.path.size() - 1)].head<2>();
        const Vec2 ab = b - a;
        const double t = ab.squaredNorm() > 0
                             ? std::clamp((p.head<2>() - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0)
                             : 0.0;
        if ((a + t * ab - p.head<2>()).norm() < 0.5) return true;
      }
    return false;
  };
  int total = 0, residue = 0;
  for (const Vec3& v : octree.occupied_voxels()) {
    if (v.z() < z_min || v.z() > z_max) continue;
    ++total;
    const auto c = g.cell_of(v.head<2>());
    if (c && !near_any(g, truth, *c) && near_path(v)) ++residue;
  }
  return total > 0 ? static_cast<double>(residue) / total : 0.0;
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
  maps::MapBuilder maps_builder;
  std::vector<double> obj_ms, map_ms;
  std::map<int, int> given;  // world object id -> keyframes it was given as a detection
  const int min_pixels = 400;
  SimObjectScores s;
  for (int k = 0; k < sim.frame_count(); k += o.keyframe_every) {
    const sim::SimFrame f = sim.render(k);
    const SE3 T_w_c = sim.camera_pose(f.time);
    // Mover ids whose pixels are masked: all, or only people and movers that move now.
    std::vector<bool> masked_id(sim.world().movers().size() + 1, true);
    masked_id[0] = false;
    if (o.detect_still_movers)
      for (const sim::SimBox& b : f.boxes)
        if (b.instance < sim::kFirstObjectId && !b.moving && b.label != "person")
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
      } else if (b.moving && b.label != "person") {
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
  // Greedy matching by centre distance, nearest pairs first; a match must lie within half the
  // truth's largest dimension (and at most 0.5 m).
  struct Pair {
    double d;
    std::size_t t, r;
  };
  std::vector<Pair> pairs;
  for (std::size_t t = 0; t < truth.size(); ++t)
    for (std::size_t r = 0; r < reported.size(); ++r) {
      const double d = (truth[t]->center - reported[r].box.center).norm();
      const double gate = std::min(0.5, std::max(0.15, 0.5 * truth[t]->size.maxCoeff()));
      // Same-label pairs first; a wrong label matches only what nothing else claims.
      const double penalty = truth[t]->label == reported[r].label ? 0.0 : 10.0;
      if (d < gate) pairs.push_back({d + penalty, t, r});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d < b.d; });
  std::vector<bool> t_used(truth.size(), false), r_used(reported.size(), false);
  std::vector<double> centre_err, size_err;
  std::vector<std::string> status(truth.size(), "missed");
  for (const Pair& p : pairs) {
    if (t_used[p.t] || r_used[p.r]) continue;
    t_used[p.t] = r_used[p.r] = true;
    ++s.matched;
    const sim::StaticObject& w = *truth[p.t];
    const semantic::SemanticObject& e = reported[p.r];
    s.label_correct += w.label == e.label;
    const double dist = (w.center - e.box.center).norm();
    centre_err.push_back(dist);
    // Footprint axes compared sorted: a square's principal axis is arbitrary.
    const double tw = std::max(w.size.x(), w.size.y()), td = std::min(w.size.x(), w.size.y());
    const double ew = std::max(e.box.size.x(), e.box.size.y()),
                 ed = std::min(e.box.size.x(), e.box.size.y());
    size_err.push_back(std::abs(ew - tw) / tw);
    size_err.push_back(std::abs(ed - td) / td);
    size_err.push_back(std::abs(e.box.size.z() - w.size.z()) / w.size.z());
    char buf[320];
    std::snprintf(buf, sizeof(buf),
                  "%-13s centre err %.3f m, size %.2fx%.2fx%.2f (truth %.2fx%.2fx%.2f), %d obs%s%s",
                  w.label.c_str(), dist, ew, ed, e.box.size.z(), tw, td, w.size.z(), e.observations,
                  w.label == e.label ? "" : ", reported as ",
                  w.label == e.label ? "" : e.label.c_str());
    status[p.t] = buf;
  }
  for (std::size_t t = 0; t < truth.size(); ++t)
    s.lines.push_back(status[t] == "missed" ? truth[t]->label + " missed" : status[t]);
  for (std::size_t r = 0; r < reported.size(); ++r)
    if (!r_used[r]) {
      char buf[160];
      const semantic::UprightBox& b = reported[r].box;
      std::snprintf(buf, sizeof(buf),
                    "extra %s at (%.2f, %.2f, %.2f), size %.2fx%.2fx%.2f, yaw %.0f deg, %d obs",
                    reported[r].label.c_str(), b.center.x(), b.center.y(), b.center.z(), b.size.x(),
                    b.size.y(), b.size.z(), b.yaw * 180 / M_PI, reported[r].observations);
      s.lines.push_back(buf);
    }
  s.recall = s.truth > 0 ? static_cast<double>(s.matched) / s.truth : 0.0;
  s.precision = s.reported > 0 ? static_cast<double>(s.matched) / s.reported : 0.0;
  s.class_correct = s.matched > 0 ? static_cast<double>(s.label_correct) / s.matched : 0.0;
  s.center_error_median = median(centre_err);
  s.size_error_median = median(size_err);
  if (o.build_maps) {
    s.grid_iou = grid_iou(sim.world(), maps_builder.grid(), maps_builder.options().grid_z_min,
                          maps_builder.options().grid_z_max);
    s.dynamic_residue =
        dynamic_residue(sim.world(), maps_builder.octree(), maps_builder.grid(),
                        maps_builder.options().grid_z_min, maps_builder.options().grid_z_max);
  }
  if (!o.out_dir.empty()) {
    db.write_outputs(o.out_dir);
    if (o.build_maps) maps_builder.write_outputs(o.out_dir);
  }
  return s;
}

}  // namespace kestrel::test
