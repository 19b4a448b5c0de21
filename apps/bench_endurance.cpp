// Endurance area: the whole system as it would run live, for a long time. The simulator streams
// `market` (walkers, a looping path) as a live camera (sim::LiveSource), frames are fed at their
// stamps' pace and the threads run free, as on the robot; the real YOLO-Fastest runs on every
// frame with hybrid rejection. Resident memory is sampled along the run, and frame_latency is
// what a live user waits from a frame's arrival to its pose. A frame that arrives while the
// tracker still has two in flight is dropped, as a live camera's would be (RunOptions::
// max_frames_in_flight), and counted. The simulator renders on the feeding thread, so on a
// 2-core machine it takes CPU a real camera would not.
#include <cmath>
#include <cstdio>

#include "apps/bench_areas.hpp"
#include "pipeline/run_job.hpp"
#include "sim/live_source.hpp"

namespace kestrel::bench {

nlohmann::json bench_endurance(const AreaOptions& o) {
  const std::string scene = "market";
  // The SLAM core's goal is stated after ten minutes of market; --quick shows the trend.
  const double duration = o.tiny ? 3.0 : o.quick ? 30.0 : 600.0;
  sim::ScenarioOverrides over;
  over.duration = duration;
  sim::LiveSource source(sim::load_scenario(scene, over));
  pipeline::RunOptions opt;
  opt.detector = "yolo";
  opt.dynamic = dynamic::FilterMode::kHybrid;
  opt.sequential = false;
  opt.paced = true;
  opt.progress = !o.tiny;
  opt.progress_label = "endurance: " + scene + ", " + std::to_string(int(duration)) +
                       " s live (real-time pace, threads free)";
  opt.strip_frames = 0;
  opt.memory_sample_s = o.tiny ? 1.0 : 10.0;
  opt.truth_masks = [&source](Timestamp t) { return source.truth_mask(t); };
  // With --work, the run's own outputs stay there (trajectory.txt, frames.csv, timing.json,
  // maps): a live run cannot be replayed, so they are all there is to see where it went wrong.
  if (!o.work_dir.empty()) opt.out_dir = o.work_dir + "/endurance";
  const pipeline::RunSummary s = pipeline::run_sequence(source, opt);
  if (!opt.out_dir.empty()) std::printf("endurance run's outputs in %s\n", opt.out_dir.c_str());

  const auto stage = [&s](const char* name) {
    const auto it = s.stages.find(name);
    return it == s.stages.end() ? pipeline::LatencySummary{} : it->second;
  };
  const auto counter = [&s](const char* name) -> std::size_t {
    const auto it = s.counters.find(name);
    return it == s.counters.end() ? 0 : it->second;
  };
  const double peak = pipeline::peak_rss_mib(s.memory);
  const double first = s.memory.empty() ? 0.0 : s.memory.front().rss_mib;
  const double last = s.memory.empty() ? 0.0 : s.memory.back().rss_mib;
  const double span_min = s.memory.empty() ? 0.0 : s.memory.back().stream_s / 60.0;
  // Growth over the second half of the run: start-up (models, first keyframes) excluded.
  double growth = 0.0;
  if (s.memory.size() >= 3) {
    const pipeline::MemorySample& mid = s.memory[s.memory.size() / 2];
    const double dt_min = (s.memory.back().stream_s - mid.stream_s) / 60.0;
    if (dt_min > 0) growth = (s.memory.back().rss_mib - mid.rss_mib) / dt_min;
  }
  const pipeline::LatencySummary lat = stage("frame_latency");
  const pipeline::LatencySummary det = stage("detection");

  std::printf("\n## Endurance (%s, %.0f s live at real-time pace, YOLO + hybrid, RGB-D + IMU)\n\n",
              scene.c_str(), duration);
  std::printf(
      "| frames | dropped (tracker busy) | tracked | lost | APE RMSE (m) | frame to pose p50 / p90 "
      "/ p99 (ms) | "
      "tracking median (ms) | detections dropped | RSS first / end / peak (MiB) | "
      "growth, 2nd half (MiB/min) | keyframes | map points |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::printf(
      "| %zu | %zu | %zu | %zu | %.4f | %.1f / %.1f / %.1f | %.1f | %zu of %zu | %.0f / %.0f / "
      "%.0f | "
      "%.1f | %zu | %zu |\n",
      s.frames, s.dropped, s.tracked, s.lost, s.ape_rmse_m, lat.p50_ms, lat.p90_ms, lat.p99_ms,
      s.tracking_ms_median, counter("detection.dropped"), s.frames - s.dropped, first, last, peak,
      growth, counter("map.keyframes"), counter("map.points"));
  std::printf(
      "\nGoals (SLAM core issue): frame to pose p99 <= 33 ms; memory <= 1024 MiB after 10 "
      "minutes of market.\n");
  // Latency along the run, in tenths of it (a minute of the ten): what grows with the map.
  const std::vector<pipeline::LatencyWindow> windows =
      pipeline::latency_windows(s.frame_latencies, duration / 10.0);
  std::printf("\nFrame to pose along the run (ms)\n\n| stream time (s) |");
  for (const auto& w : windows) std::printf(" %.0f-%.0f |", w.from_s, w.to_s);
  std::printf("\n|---|");
  for (std::size_t i = 0; i < windows.size(); ++i) std::printf("---|");
  const std::pair<const char*, double pipeline::LatencySummary::*> rows[] = {
      {"p50", &pipeline::LatencySummary::p50_ms}, {"p99", &pipeline::LatencySummary::p99_ms}};
  for (const auto& [name, field] : rows) {
    std::printf("\n| %s |", name);
    for (const auto& w : windows) std::printf(" %.1f |", w.latency.*field);
  }
  std::printf("\n");
  nlohmann::json by_window = nlohmann::json::array();
  for (const auto& w : windows) {
    by_window.push_back({{"from_s", w.from_s},
                         {"to_s", w.to_s},
                         {"frames", w.latency.count},
                         {"p50", w.latency.p50_ms},
                         {"p99", w.latency.p99_ms}});
  }
  // The stages that grow as a revisited place gathers keyframes (README, "Endurance"): their
  // medians per tenth of the run, by wall time, which a live run shares with its stream.
  const char* const growing[] = {"tracking.match",
                                 "tracking",
                                 "mapping.keyframe",
                                 "mapping.keyframe_finish",
                                 "mapping.keyframe_finish.ba_gather",
                                 "mapping.keyframe_finish.keyframe_culling",
                                 "mapping.local_ba"};
  std::printf("\nStages along the run, median per tenth of it (ms)\n\n| stage |");
  for (int i = 0; i < 10; ++i) std::printf(" %d |", i + 1);
  std::printf("\n|---|");
  for (int i = 0; i < 10; ++i) std::printf("---|");
  nlohmann::json stages_by_window = nlohmann::json::object();
  for (const char* name : growing) {
    const auto it = s.stage_timelines.find(name);
    if (it == s.stage_timelines.end()) continue;
    std::printf("\n| %s |", name);
    // A tenth without a sample (no keyframe in it) stays empty rather than shifting the rest.
    std::vector<double> p50(10, -1.0);
    for (const auto& w : pipeline::latency_windows(it->second, duration / 10.0)) {
      const auto k = static_cast<std::size_t>(std::lround(w.from_s / (duration / 10.0)));
      if (k < p50.size()) p50[k] = w.latency.p50_ms;
    }
    nlohmann::json medians = nlohmann::json::array();
    for (const double v : p50) {
      if (v < 0) {
        std::printf(" - |");
        medians.push_back(nullptr);
      } else {
        std::printf(" %.1f |", v);
        medians.push_back(v);
      }
    }
    stages_by_window[name] = medians;
  }
  std::printf("\n");

  nlohmann::json samples = nlohmann::json::array();
  for (const pipeline::MemorySample& m : s.memory) samples.push_back({m.stream_s, m.rss_mib});
  return {{"scenario", scene},
          {"outputs", opt.out_dir},
          {"duration_s", duration},
          {"wall_seconds", s.wall_seconds},
          {"frames", s.frames},
          {"dropped", s.dropped},
          {"tracked", s.tracked},
          {"lost", s.lost},
          {"ape_rmse_m", s.ape_rmse_m},
          {"frame_latency_ms",
           {{"p50", lat.p50_ms}, {"p90", lat.p90_ms}, {"p99", lat.p99_ms}, {"max", lat.max_ms}}},
          {"frame_latency_ms_along_run", by_window},
          {"stage_p50_ms_along_run", stages_by_window},
          {"tracking_ms_median", s.tracking_ms_median},
          {"detection_ms_median", det.p50_ms},
          {"detections_dropped", counter("detection.dropped")},
          {"rss_mib_first", first},
          {"rss_mib_end", last},
          {"rss_mib_peak", peak},
          {"rss_growth_mib_per_min_second_half", growth},
          {"rss_span_min", span_min},
          {"rss_samples_s_mib", samples},
          {"keyframes", counter("map.keyframes")},
          {"map_points", counter("map.points")},
          {"removal_percent", s.removal.removed_percent()},
          {"static_kept_percent", s.removal.kept_percent()}};
}

}  // namespace kestrel::bench
