// Tracking cost per frame on one thread at 640x480: feature extraction on a real TUM frame, and
// the whole tracker (extraction, matching, pose optimization, keyframes with inline local BA)
// on the rendered sequence of the tracking tests. Counters report per-stage medians in ms.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <vector>

#include "io/image_io.hpp"
#include "tests/test_paths.hpp"
#include "tests/tracking/synthetic_scene.hpp"
#include "tracking/tracker.hpp"

namespace {

using namespace kestrel;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

void BM_ExtractTumFrame(benchmark::State& state) {
  PinholeCamera cam;
  cam.fx = 535.4;
  cam.fy = 539.2;
  cam.cx = 320.1;
  cam.cy = 247.6;
  RgbdFrame f;
  f.color = io::load_image(test::shared_data("tum_fr3/frame/rgb_1341846313.592026.png").string(),
                           io::ImageKind::kColor);
  f.depth = io::load_image(test::shared_data("tum_fr3/frame/depth_1341846313.592088.png").string(),
                           io::ImageKind::kDepth);
  const tracking::FeatureExtractor ex(cam);
  std::size_t n = 0;
  for (auto _ : state) {
    const auto features = ex.extract(f);
    n = features.size();
    benchmark::DoNotOptimize(n);
  }
  state.counters["features"] = static_cast<double>(n);
}
BENCHMARK(BM_ExtractTumFrame)->Unit(benchmark::kMillisecond);

void BM_TrackSyntheticSequence(benchmark::State& state) {
  PinholeCamera cam;
  cam.fx = cam.fy = 525.0;
  cam.cx = 319.5;
  cam.cy = 239.5;
  const auto scene = test::SyntheticScene::office();
  const auto path = test::smooth_path(60);
  std::vector<RgbdFrame> frames;
  for (const SE3& T : path) frames.push_back(scene.render(cam, T));
  std::vector<double> total, extract, match, optimize, keyframe, non_kf_total;
  for (auto _ : state) {
    tracking::Tracker tracker(cam);
    for (const RgbdFrame& f : frames) {
      const tracking::TrackResult r = tracker.track(f);
      total.push_back(r.times.total_ms);
      extract.push_back(r.times.extract_ms);
      match.push_back(r.times.match_ms);
      optimize.push_back(r.times.optimize_ms);
      if (r.new_keyframe) {
        keyframe.push_back(r.times.keyframe_ms);
      } else {
        non_kf_total.push_back(r.times.total_ms);
      }
    }
  }
  state.counters["frames"] = static_cast<double>(total.size());
  state.counters["median_total_ms"] = median(total);
  state.counters["median_extract_ms"] = median(extract);
  state.counters["median_match_ms"] = median(match);
  state.counters["median_optimize_ms"] = median(optimize);
  state.counters["median_keyframe_ms"] = median(keyframe);
  state.counters["median_tracking_only_ms"] = median(non_kf_total);
  state.counters["max_total_ms"] = *std::max_element(total.begin(), total.end());
}
BENCHMARK(BM_TrackSyntheticSequence)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
