// The dynamic filter per frame (dynamic::classify_features) on one thread at 640x480: two
// consecutive rendered cafe frames with movers in view, the tracker's own ~1000 features with
// their sensor depth, the mover boxes a detector gives (the simulator's boxes of dynamic-class
// movers), the gyro rotation and the previous depth image: what the System hands the filter.
// Counters: median_ms (per call, over all iterations), features, boxes. The "cached" variants
// give the filter the previous frame's flow pyramid as the System does from its second frame on;
// HalfResLk runs the flow on the half-resolution image (lk_base_level 1, 9 px window, 2 levels
// above it, 10 iterations to 0.1 px) in place of the seed's default (15 px window at full
// resolution, 3 levels above it, 20 iterations to 0.03 px), for the ratio between the two.
// The rows above hand the filter the gyro's rotation but not the IMU's translation; the System
// hands it both in RGB-D + IMU (its default on Kestrel sequences) and neither in plain RGB-D,
// so two more rows time exactly those inputs: Imu (the rotation, the predicted translation with
// its sigma, the current depth image) and NoImu (depth images only).
// Removal figures against the masks come from `kestrel bench dynamic`.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <vector>

#include "detect/dynamic_classes.hpp"
#include "dynamic/dynamic_filter.hpp"
#include "io/cv_image.hpp"
#include "pipeline/system.hpp"
#include "sim/scenario.hpp"
#include "sim/simulator.hpp"
#include "tracking/feature_extractor.hpp"

namespace {

using namespace kestrel;

struct Pair {
  Image prev_gray, cur_gray, prev_depth, cur_depth;
  dynamic::DynamicFilterInput input;  // pointers into this struct: never copied
  // What the System adds in RGB-D + IMU: the IMU's translation since the previous frame (here
  // the true one: the predictor's millimetres of error do not change the work) and its sigmas
  // one frame after a fix, as the System computes them.
  Vec3 t_cur_prev = Vec3::Zero();
  pipeline::InertialPriorSigmas sigmas{};
};

Image gray_of(const Image& color) {
  cv::Mat g;
  cv::cvtColor(io::as_mat(color), g, cv::COLOR_BGR2GRAY);
  return io::to_image(g);
}

const Pair& cafe_pair() {
  static const Pair* pair = [] {
    sim::ScenarioOverrides over;
    over.duration = 3.0;
    sim::Simulator sim(sim::load_scenario("cafe", over));
    const Calibration& calib = sim.calibration();
    const int k = std::min(sim.frame_count() - 1, 61);
    const sim::SimFrame f0 = sim.render(k - 1), f1 = sim.render(k);
    auto* p = new Pair;
    p->prev_gray = gray_of(f0.color);
    p->cur_gray = gray_of(f1.color);
    p->prev_depth = f0.depth;
    p->cur_depth = f1.depth;
    const tracking::FeatureExtractor extractor(calib.camera);
    const tracking::FrameFeatures ff =
        extractor.extract(f1.color, nullptr, &f1.depth, calib.depth_scale);
    dynamic::DynamicFilterInput& in = p->input;
    in.prev_gray = &p->prev_gray;
    in.cur_gray = &p->cur_gray;
    for (const auto& kp : ff.keypoints) in.points.push_back(kp.px);
    in.depth_m = ff.sensor_depth;
    in.K = calib.camera.K();
    const SE3 T_w_c0 = f0.body.T_w_b * calib.T_body_camera;
    const SE3 T_w_c1 = f1.body.T_w_b * calib.T_body_camera;
    in.R_cur_prev = (T_w_c1.inverse() * T_w_c0).rotation();
    p->t_cur_prev = (T_w_c1.inverse() * T_w_c0).translation();
    p->sigmas = pipeline::inertial_prior_sigmas(pipeline::SystemOptions{}, f1.time - f0.time);
    in.prev_depth = &p->prev_depth;
    in.depth_scale = calib.depth_scale;
    for (const sim::SimBox& b : f1.boxes) {
      if (b.instance < 1000 && detect::is_dynamic_class(b.label)) {
        in.boxes.push_back({float(b.x_min), float(b.y_min), float(b.x_max), float(b.y_max)});
      }
    }
    return p;
  }();
  return *pair;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// Which of the System's inputs a row hands the filter (see the top of this file).
enum class Inputs { kGyro, kImu, kNoImu };

void run(benchmark::State& state, dynamic::FilterMode mode, bool boxes, bool cached,
         bool half_res_lk = false, Inputs inputs = Inputs::kGyro) {
  cv::setNumThreads(1);
  const Pair& pair = cafe_pair();
  dynamic::DynamicFilterInput in = pair.input;
  if (!boxes) in.boxes.clear();
  if (inputs != Inputs::kGyro) in.cur_depth = &pair.cur_depth;
  if (inputs == Inputs::kNoImu) in.R_cur_prev.reset();
  if (inputs == Inputs::kImu) {
    in.t_cur_prev = pair.t_cur_prev;
    in.prior_translation_sigma_m = pair.sigmas.translation_m;
    in.prior_rotation_sigma_rad = pair.sigmas.rotation_rad;
  }
  dynamic::DynamicFilterOptions opt;
  opt.mode = mode;
  if (half_res_lk) dynamic::use_half_resolution_flow(opt);
  // The previous frame's pyramid, as the System keeps it from the call before.
  const dynamic::FlowPyramid prev_pyr = dynamic::build_flow_pyramid(*in.prev_gray, opt);
  std::vector<double> ms;
  std::size_t dyn = 0;
  for (auto _ : state) {
    dynamic::FlowPyramid cur_pyr;
    if (cached) {
      in.prev_pyramid = &prev_pyr;
      in.cur_pyramid_out = &cur_pyr;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const dynamic::DynamicFilterResult r = dynamic::classify_features(in, opt);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    dyn = r.count(dynamic::FeatureLabel::kDynamic);
    benchmark::DoNotOptimize(dyn);
  }
  state.counters["median_ms"] = median(ms);
  state.counters["features"] = static_cast<double>(in.points.size());
  state.counters["boxes"] = static_cast<double>(in.boxes.size());
  state.counters["dynamic"] = static_cast<double>(dyn);
}

void BM_DynamicFilterHybrid(benchmark::State& s) {
  run(s, dynamic::FilterMode::kHybrid, true, false);
}
void BM_DynamicFilterHybridCachedPyramid(benchmark::State& s) {
  run(s, dynamic::FilterMode::kHybrid, true, true);
}
void BM_DynamicFilterGeometry(benchmark::State& s) {
  run(s, dynamic::FilterMode::kGeometryOnly, false, false);
}
void BM_DynamicFilterGeometryCachedPyramid(benchmark::State& s) {
  run(s, dynamic::FilterMode::kGeometryOnly, false, true);
}
void BM_DynamicFilterHybridCachedPyramidHalfResLk(benchmark::State& s) {
  run(s, dynamic::FilterMode::kHybrid, true, true, true);
}
void BM_DynamicFilterHybridCachedPyramidImu(benchmark::State& s) {
  run(s, dynamic::FilterMode::kHybrid, true, true, false, Inputs::kImu);
}
void BM_DynamicFilterHybridCachedPyramidNoImu(benchmark::State& s) {
  run(s, dynamic::FilterMode::kHybrid, true, true, false, Inputs::kNoImu);
}
BENCHMARK(BM_DynamicFilterHybrid)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DynamicFilterHybridCachedPyramid)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DynamicFilterHybridCachedPyramidHalfResLk)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DynamicFilterHybridCachedPyramidImu)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DynamicFilterHybridCachedPyramidNoImu)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DynamicFilterGeometry)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DynamicFilterGeometryCachedPyramid)->Unit(benchmark::kMillisecond);

}  // namespace
