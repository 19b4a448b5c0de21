// The mapping stages that grow with a place seen again and again: 700 points, the window's 11
// keyframes and as many earlier ones as the argument, each seeing a point with probability one
// half, so a point's views grow with the revisits as on a long run of market.
//  * Local bundle adjustment (mapping/local_ba.hpp); condensed: the fixed keyframes' views
//    enter as one model per point (LocalBaOptions::condense_fixed_views).
//  * What the tracking thread does with each keyframe on such a place: the keyframe-culling
//    test of each keyframe connected to the newest (Map::is_redundant, as Tracker's culling asks
//    it, nothing erased), and local BA's gather.
#include <benchmark/benchmark.h>

#include <random>

#include "mapping/local_ba.hpp"
#include "mapping/map.hpp"

namespace kestrel::mapping {
namespace {

Map revisited_place(const PinholeCamera& cam, int keyframes) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> ux(-2.5, 2.5), uy(-1.8, 1.8), uz(3.0, 6.0), u01(0, 1);
  constexpr int kPoints = 700;
  std::vector<Vec3> truth;
  for (int i = 0; i < kPoints; ++i) truth.emplace_back(ux(rng), uy(rng), uz(rng));
  Map map;
  std::vector<PointId> ids(kPoints, kNoPoint);
  for (int k = 0; k < keyframes; ++k) {
    const SE3 T_w_c(SO3::exp(Vec3(0.0, 0.02 * std::sin(0.3 * k), 0.0)),
                    Vec3(0.3 * std::sin(0.2 * k), 0.05 * std::cos(0.5 * k), 0.0));
    const SE3 T_c_w = T_w_c.inverse();
    FrameFeatures f;
    f.width = cam.width;
    f.height = cam.height;
    std::vector<int> seen;
    for (int i = 0; i < kPoints; ++i) {
      const Vec3 p_c = T_c_w * truth[static_cast<std::size_t>(i)];
      // The newest keyframes see every point: they are the window.
      if (k < keyframes - 11 && u01(rng) < 0.5) continue;
      tracking::Keypoint kp;
      kp.un = kp.px = *cam.project(p_c) + 0.7 * Vec2(n01(rng), n01(rng));
      f.keypoints.push_back(kp);
      f.descriptors.emplace_back();
      f.depth.push_back(p_c.z() * (1.0 + 0.003 * n01(rng)));
      f.points_c.push_back(p_c);
      f.status.push_back(tracking::FeatureStatus::kStatic);
      seen.push_back(i);
    }
    const KeyframeId kid = map.add_keyframe(k, SE3::exp(0.002 * Vec6::Random()) * T_w_c, f);
    for (std::size_t j = 0; j < seen.size(); ++j) {
      const auto i = static_cast<std::size_t>(seen[j]);
      if (ids[i] == kNoPoint) {
        ids[i] = map.add_point(truth[i] + 0.01 * Vec3(n01(rng), n01(rng), n01(rng)), kid,
                               static_cast<int>(j));
      } else {
        map.add_observation(ids[i], kid, static_cast<int>(j));
      }
    }
  }
  for (int k = 0; k < keyframes; ++k) map.update_connections(k);
  return map;
}

void BM_LocalBaRevisitedPlace(benchmark::State& state) {
  const PinholeCamera cam;  // 640x480, f 525: the simulator's camera
  const int earlier = static_cast<int>(state.range(0));
  const Map map = revisited_place(cam, earlier + 11);
  LocalBaOptions options;
  options.condense_fixed_views = state.range(1) != 0;
  const auto pb = gather_local_ba(map, earlier + 10, options);
  if (!pb) {
    state.SkipWithError("no local BA problem");
    return;
  }
  for (auto _ : state) benchmark::DoNotOptimize(solve_local_ba(*pb, cam, options));
  state.counters["observations"] = static_cast<double>(pb->observations.size());
  state.counters["fixed"] = static_cast<double>(pb->fixed.size());
}
BENCHMARK(BM_LocalBaRevisitedPlace)
    ->ArgNames({"earlier", "condensed"})
    ->ArgsProduct({{10, 40, 100}, {0, 1}})
    ->Unit(benchmark::kMillisecond);

void BM_KeyframeCullingTest(benchmark::State& state) {
  const PinholeCamera cam;
  const int earlier = static_cast<int>(state.range(0));
  const Map map = revisited_place(cam, earlier + 11);
  const KeyframeId newest = earlier + 10;
  std::vector<KeyframeId> candidates;
  for (const auto& [id, w] : map.keyframe(newest)->connections) {
    (void)w;
    candidates.push_back(id);
  }
  int redundant = 0;
  for (auto _ : state) {
    redundant = 0;
    for (KeyframeId id : candidates) redundant += map.is_redundant(id, 40.0, 3, 0.9) ? 1 : 0;
    benchmark::DoNotOptimize(redundant);
  }
  state.counters["candidates"] = static_cast<double>(candidates.size());
  state.counters["redundant"] = redundant;
}
BENCHMARK(BM_KeyframeCullingTest)
    ->ArgName("earlier")
    ->Arg(40)
    ->Arg(100)
    ->Arg(300)
    ->Unit(benchmark::kMillisecond);

void BM_LocalBaGather(benchmark::State& state) {
  const PinholeCamera cam;
  const int earlier = static_cast<int>(state.range(0));
  const Map map = revisited_place(cam, earlier + 11);
  std::size_t observations = 0;
  for (auto _ : state) {
    const auto pb = gather_local_ba(map, earlier + 10, LocalBaOptions{});
    observations = pb ? pb->observations.size() : 0;
    benchmark::DoNotOptimize(observations);
  }
  state.counters["observations"] = static_cast<double>(observations);
}
BENCHMARK(BM_LocalBaGather)
    ->ArgName("earlier")
    ->Arg(40)
    ->Arg(100)
    ->Arg(300)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace kestrel::mapping
