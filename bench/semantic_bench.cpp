// Object database and clean-map updates per keyframe (semantic/, maps/) on rendered cafe
// keyframes with ground-truth poses, static boxes and mover masks; and the time to write the
// output files. Issue 6's budget: update median <= 20 ms on one core, outputs <= 2 s.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>
#include <vector>

#include "maps/map_builder.hpp"
#include "semantic/object_database.hpp"
#include "sim/simulator.hpp"

namespace {

using namespace kestrel;

struct Keyframe {
  sim::SimFrame frame;
  SE3 T_w_c;
  std::vector<std::uint8_t> static_mask;
  std::vector<detect::Detection> boxes;
};

struct Scene {
  Calibration calib;
  std::vector<Keyframe> keyframes;
};

const Scene& scene() {
  static const std::unique_ptr<Scene> s = [] {
    auto out = std::make_unique<Scene>();
    sim::Simulator sim(sim::load_scenario("cafe"));
    out->calib = sim.calibration();
    for (int k = 0; k < sim.frame_count(); k += 45) {
      Keyframe kf;
      kf.frame = sim.render(k);
      kf.T_w_c = sim.camera_pose(kf.frame.time);
      const Image& m = kf.frame.mask;
      kf.static_mask.resize(static_cast<std::size_t>(m.width) * m.height);
      for (int v = 0; v < m.height; ++v)
        for (int u = 0; u < m.width; ++u)
          kf.static_mask[static_cast<std::size_t>(v) * m.width + u] =
              m.row<std::uint16_t>(v)[u] == 0;
      for (const sim::SimBox& b : kf.frame.boxes) {
        if (b.instance < sim::kFirstObjectId || b.pixels < 400) continue;
        detect::Detection d;
        d.label = b.label;
        d.score = 0.9f;
        d.x_min = static_cast<float>(b.x_min);
        d.y_min = static_cast<float>(b.y_min);
        d.x_max = static_cast<float>(b.x_max);
        d.y_max = static_cast<float>(b.y_max);
        kf.boxes.push_back(d);
      }
      out->keyframes.push_back(std::move(kf));
    }
    return out;
  }();
  return *s;
}

semantic::ObjectKeyframe object_input(const Scene& s, std::size_t i, std::int64_t id) {
  const Keyframe& k = s.keyframes[i];
  semantic::ObjectKeyframe in;
  in.keyframe_id = id;
  in.T_w_c = k.T_w_c;
  in.stamp = k.frame.stamp;
  in.depth = &k.frame.depth;
  in.depth_scale = s.calib.depth_scale;
  in.camera = s.calib.camera;
  in.static_mask = &k.static_mask;
  in.static_boxes = k.boxes;
  return in;
}

maps::MapKeyframe map_input(const Scene& s, std::size_t i) {
  const Keyframe& k = s.keyframes[i];
  maps::MapKeyframe in;
  in.T_w_c = k.T_w_c;
  in.color = &k.frame.color;
  in.depth = &k.frame.depth;
  in.depth_scale = s.calib.depth_scale;
  in.camera = s.calib.camera;
  in.static_mask = &k.static_mask;
  return in;
}

void BM_ObjectDatabaseUpdate(benchmark::State& state) {
  const Scene& s = scene();
  semantic::ObjectDatabase db;
  std::int64_t id = 0;
  for (auto _ : state) {
    const auto in = object_input(s, static_cast<std::size_t>(id) % s.keyframes.size(), id);
    benchmark::DoNotOptimize(db.update(in));
    ++id;
  }
  state.counters["objects"] = static_cast<double>(db.all_objects().size());
}
BENCHMARK(BM_ObjectDatabaseUpdate)->Unit(benchmark::kMillisecond);

void BM_MapBuilderInsert(benchmark::State& state) {
  const Scene& s = scene();
  maps::MapBuilder b;
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(b.insert(map_input(s, i++ % s.keyframes.size())));
  state.counters["octree_leaves"] = static_cast<double>(b.octree().leaf_count());
}
BENCHMARK(BM_MapBuilderInsert)->Unit(benchmark::kMillisecond);

void BM_WriteOutputs(benchmark::State& state) {
  const Scene& s = scene();
  maps::MapBuilder b;
  semantic::ObjectDatabase db;
  for (std::size_t i = 0; i < s.keyframes.size(); ++i) {
    b.insert(map_input(s, i));
    db.update(object_input(s, i, static_cast<std::int64_t>(i)));
  }
  const auto dir = std::filesystem::temp_directory_path() / "kestrel-semantic-bench";
  for (auto _ : state) {
    b.write_outputs(dir.string());
    db.write_outputs(dir.string());
  }
  state.counters["cloud_points"] = static_cast<double>(b.cloud().size());
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_WriteOutputs)->Unit(benchmark::kMillisecond);

}  // namespace
