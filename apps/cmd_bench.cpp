// `kestrel bench [--quick] [--json FILE]`: the figures of every part on the named synthetic
// scenarios, one markdown table per area plus one JSON file. Scenes are rendered by the
// simulator into a temporary folder and run through the same pipeline::run_sequence as
// `kestrel run`. Speed figures are medians (per-frame medians of each stage; medians over
// scenarios); comparisons are ratios between runs of this same invocation.
#include <sys/resource.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "apps/bench_areas.hpp"
#include "apps/commands.hpp"
#include "core/error.hpp"
#include "detect/oracle_detector.hpp"
#include "detect/yolo_fastest.hpp"
#include "io/dataset.hpp"
#include "io/kestrel_sequence.hpp"
#include "pipeline/progress.hpp"
#include "pipeline/run_job.hpp"
#include "pipeline/stage_stats.hpp"
#include "sim/scenario.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"

namespace {

namespace fs = std::filesystem;
using kestrel::dynamic::FilterMode;
using nlohmann::json;

struct BenchFlags {
  bool quick = false;
  std::string json_path;
  std::string work_dir;
  bool keep = false;
  bool tiny = false;              // the smallest inputs, for the test that runs every area
  int seeds = 0;                  // accuracy scenes per scenario; 0: 1 with --quick, else 3
  std::vector<std::string> only;  // areas to run; empty: all
};

const std::vector<std::string> kAreas = {"accuracy",  "dynamic", "evaluation", "imu",   "objects",
                                         "telemetry", "video",   "endurance",  "memory"};

// One way of running the system (a row of the accuracy table).
struct Mode {
  std::string name;
  std::string detector;  // yolo | oracle | none
  FilterMode dynamic;
  double false_negative_rate = 0.0;
  std::string sensor = "auto";  // RunOptions::mode: auto is RGB-D + IMU on Kestrel scenes
};

const std::vector<Mode>& all_modes() {
  static const std::vector<Mode> modes = {
      {"hybrid+yolo", "yolo", FilterMode::kHybrid},
      {"hybrid+oracle", "oracle", FilterMode::kHybrid},
      {"hybrid+oracle-fn20", "oracle", FilterMode::kHybrid, 0.2},
      {"detection+yolo", "yolo", FilterMode::kDetectionOnly},
      {"geometry", "none", FilterMode::kGeometryOnly},
      {"off", "none", FilterMode::kOff},
      // The same without the IMU: what the inertial prediction, dead reckoning and bridging
      // are worth.
      {"off-visual", "none", FilterMode::kOff, 0.0, "rgbd"},
  };
  return modes;
}

struct Scene {
  std::string scenario;
  bool movers = true;
  double duration = 5.0;
  std::vector<std::string> modes;  // names from all_modes()
  long long seed = -1;             // the world's random draw; negative: the scenario file's
};

struct SceneResult {
  Scene scene;
  int frames = 0;
  double render_fps = 0.0;
  std::string dir;
};

struct RunResult {
  std::string scenario;
  bool movers = true;
  long long seed = -1;
  Mode mode;
  kestrel::pipeline::RunSummary summary;
};

std::string scene_name(const Scene& s) {
  return s.scenario + (s.movers ? "" : " (no movers)") +
         (s.seed >= 0 ? " seed " + std::to_string(s.seed) : "");
}

// Each scene again with seeds - 1 further draws of its world (walkers' paths, textures, sensor
// noise): one 60 s run of a dynamic scene is one draw, and across draws the same code's APE on
// uav-zigzag spanned 0.31 to 1.74 m, so a single figure cannot tell a change from luck. The
// first draw keeps the scenario's own seed; when there are more, every draw is named.
std::vector<Scene> with_seeds(const std::vector<Scene>& scenes, int seeds) {
  if (seeds <= 1) return scenes;
  std::vector<Scene> out;
  for (const Scene& s : scenes) {
    const auto own = static_cast<long long>(kestrel::sim::load_scenario(s.scenario).seed);
    for (int i = 0; i < seeds; ++i) {
      Scene d = s;
      d.seed = own + i;
      out.push_back(d);
    }
  }
  return out;
}

std::vector<Scene> plan(bool quick) {
  std::vector<std::string> every;
  for (const Mode& m : all_modes()) every.push_back(m.name);
  const std::vector<std::string> static_modes = {"hybrid+yolo", "geometry", "off", "off-visual"};
  if (quick) {
    return {{"cafe", true, 5.0, every},
            {"market", true, 4.0, every},
            {"cafe", false, 4.0, static_modes}};
  }
  std::vector<Scene> scenes;
  for (const char* s : {"cafe", "market", "uav-zigzag", "ugv-loop"}) {
    scenes.push_back({s, true, 15.0, every});
  }
  scenes.push_back({"cafe", false, 15.0, static_modes});
  scenes.push_back({"office-static", true, 15.0, static_modes});
  // The SLAM core issue wants corridor-dark tracked end to end with no lost frame: its whole
  // 40 s (the dark turn facing a bare end wall comes at 18 s), with rejection and without.
  scenes.push_back({"corridor-dark", true, 40.0, {"hybrid+yolo", "off"}});
  return scenes;
}

const Mode& mode_named(const std::string& name) {
  for (const Mode& m : all_modes()) {
    if (m.name == name) return m;
  }
  throw kestrel::Error("bench: unknown mode " + name);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  return kestrel::pipeline::percentile(std::move(v), 50.0);
}

std::string f(const char* format, double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

double stage_p50(const kestrel::pipeline::RunSummary& s, const std::string& stage) {
  const auto it = s.stages.find(stage);
  return it == s.stages.end() ? 0.0 : it->second.p50_ms;
}

// The detector alone on the rendered frames: per-frame latency samples.
std::vector<double> time_detector(kestrel::detect::Detector& detector, const std::string& dir,
                                  std::size_t max_frames) {
  auto source = kestrel::io::open_dataset("kestrel:" + dir);
  std::vector<double> ms;
  while (auto m = source->next()) {
    const auto* frame = std::get_if<kestrel::RgbdFrame>(&*m);
    if (!frame) continue;
    const auto t0 = std::chrono::steady_clock::now();
    static_cast<void>(detector.detect(frame->color, frame->t));
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (ms.size() >= max_frames) break;
  }
  return ms;
}

// bench/results/{quick,full}-DATE.json for every area; with --only, the areas' names replace
// "full" (quick-dynamic-..., dynamic+imu-...), so a partial run never passes for a full one.
std::string default_json_path(bool quick, const std::vector<std::string>& only) {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y%m%d-%H%M%S", &tm);
  std::string what;
  for (const std::string& a : only) what += (what.empty() ? "" : "+") + a;
  std::string name =
      quick ? (what.empty() ? "quick" : "quick-" + what) : (what.empty() ? "full" : what);
  return "bench/results/" + name + "-" + buf + ".json";
}

void run_bench(const BenchFlags& flags) {
  const auto start = std::chrono::steady_clock::now();
  for (const std::string& a : flags.only) {
    if (std::find(kAreas.begin(), kAreas.end(), a) == kAreas.end()) {
      throw kestrel::Error("bench: unknown area '" + a +
                           "' (--only takes a list of: accuracy, dynamic, "
                           "evaluation, imu, objects, telemetry, video, endurance, memory)");
    }
  }
  const auto want = [&](const std::string& area) {
    return flags.only.empty() ||
           std::find(flags.only.begin(), flags.only.end(), area) != flags.only.end();
  };
  // --tiny keeps the accuracy area's shape with 2 s scenes and two modes.
  std::vector<Scene> scenes = want("accuracy") ? plan(flags.quick) : std::vector<Scene>{};
  if (flags.tiny && !scenes.empty()) scenes = {{"cafe", true, 2.0, {"hybrid+oracle", "off"}}};
  const int seeds = flags.seeds > 0 ? flags.seeds : (flags.quick || flags.tiny ? 1 : 3);
  scenes = with_seeds(scenes, seeds);
  const fs::path work = flags.work_dir.empty() ? fs::temp_directory_path() /
                                                     ("kestrel-bench-" + std::to_string(getpid()))
                                               : fs::path(flags.work_dir);
  fs::create_directories(work);
  std::size_t total_runs = 0;
  for (const Scene& s : scenes) total_runs += s.modes.size();
  std::printf("kestrel bench%s: %zu scenes, %zu runs, work folder %s\n",
              flags.quick ? " --quick" : "", scenes.size(), total_runs, work.c_str());

  // 1. Render every scene.
  std::vector<SceneResult> rendered;
  for (const Scene& s : scenes) {
    kestrel::sim::ScenarioOverrides over;
    over.duration = s.duration;
    over.no_movers = !s.movers;
    over.seed = s.seed;
    kestrel::sim::Simulator sim(kestrel::sim::load_scenario(s.scenario, over));
    SceneResult r{s, 0, 0.0,
                  (work / (s.scenario + (s.movers ? "" : "-static") +
                           (s.seed >= 0 ? "-seed" + std::to_string(s.seed) : "")))
                      .string()};
    std::printf("rendering %s, %.0f s (%d frames)\n", scene_name(s).c_str(), s.duration,
                sim.frame_count());
    fs::remove_all(r.dir);
    kestrel::pipeline::ProgressBar bar(static_cast<std::size_t>(sim.frame_count()), "frames");
    const auto rec = kestrel::sim::record_sequence(
        sim, r.dir, [&bar](int done, int) { bar.update(static_cast<std::size_t>(done)); });
    r.frames = rec.frames;
    r.render_fps = rec.frames / std::max(rec.render_seconds, 1e-9);
    rendered.push_back(r);
  }

  // 2. Run every (scene, mode).
  std::printf("running %zu configurations\n", total_runs);
  kestrel::pipeline::ProgressBar bar(total_runs, "runs");
  std::vector<RunResult> runs;
  for (const SceneResult& sr : rendered) {
    for (const std::string& mode_name : sr.scene.modes) {
      const Mode& mode = mode_named(mode_name);
      bar.update(runs.size(), sr.scene.scenario + " " + mode.name);
      auto source = kestrel::io::open_dataset("kestrel:" + sr.dir);
      kestrel::pipeline::RunOptions opt;
      opt.dataset_dir = sr.dir;
      opt.detector = mode.detector;
      opt.dynamic = mode.dynamic;
      opt.mode = mode.sensor;
      opt.oracle.false_negative_rate = mode.false_negative_rate;
      opt.progress = false;
      opt.strip_frames = 0;
      // One mode per scene writes its outputs, as kestrel run --out does, to time the writing.
      if (mode.name == "hybrid+yolo") opt.out_dir = sr.dir + "-outputs";
      runs.push_back({sr.scene.scenario, sr.scene.movers, sr.scene.seed, mode,
                      kestrel::pipeline::run_sequence(*source, opt)});
      bar.update(runs.size(), sr.scene.scenario + " " + mode.name);
    }
  }

  // 3. The detectors alone, on the first scene's frames.
  std::printf("timing the detectors\n");
  const std::size_t det_frames = flags.tiny ? 5 : flags.quick ? 40 : 150;
  std::map<std::string, std::vector<double>> detector_ms;
  if (!rendered.empty()) {
    kestrel::detect::YoloFastestOptions v11;
    v11.model = kestrel::detect::YoloModel::kV11;
    kestrel::detect::YoloFastest yolo(kestrel::detect::find_models_dir(), v11);
    detector_ms["yolo-fastest"] = time_detector(yolo, rendered.front().dir, det_frames);
    kestrel::detect::YoloFastest yolo_xl(
        kestrel::detect::find_models_dir(),
        kestrel::detect::pipeline_yolo_options(kestrel::detect::YoloModel::kV11Xl));
    detector_ms["yolo-fastest-xl"] = time_detector(yolo_xl, rendered.front().dir, det_frames);
    kestrel::detect::OracleDetector oracle(
        kestrel::io::read_boxes(rendered.front().dir + "/boxes.csv"));
    detector_ms["oracle"] = time_detector(oracle, rendered.front().dir, det_frames);
  }

  // 4. Tables and JSON.
  json j;
  j["version"] = KESTREL_VERSION;
  j["quick"] = flags.quick;
  j["hardware_threads"] = std::thread::hardware_concurrency();
  for (const SceneResult& sr : rendered) {
    j["scenes"].push_back({{"scenario", sr.scene.scenario},
                           {"movers", sr.scene.movers},
                           {"seed", sr.scene.seed},
                           {"duration_s", sr.scene.duration},
                           {"frames", sr.frames},
                           {"render_fps", sr.render_fps}});
  }

  if (!runs.empty()) {
    std::printf("\n## Accuracy (APE RMSE, SE(3)-aligned, metres)\n\n");
    // "frame to frame": lost to the map, their step fixed by depth and corners (tracked);
    // "bridged": the local map restarted there, at the IMU's pose (tracked).
    std::printf(
        "| scene | mode | detector | APE RMSE (m) | vs off | tracked | frame to frame | bridged "
        "| lost |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|\n");
    auto off_of = [&](const RunResult& r) -> const RunResult* {
      for (const RunResult& o : runs) {
        if (o.scenario == r.scenario && o.movers == r.movers && o.seed == r.seed &&
            o.mode.name == "off") {
          return &o;
        }
      }
      return nullptr;
    };
    for (const RunResult& r : runs) {
      const auto& s = r.summary;
      const RunResult* off = off_of(r);
      const bool ratio = off && off->summary.ape_rmse_m > 0 && s.ape_rmse_m >= 0;
      std::printf("| %s | %s | %s | %s | %s | %zu/%zu | %zu | %zu | %zu |\n",
                  scene_name({r.scenario, r.movers, 0, {}, r.seed}).c_str(), r.mode.name.c_str(),
                  r.mode.detector.c_str(),
                  s.ape_rmse_m >= 0 ? f("%.4f", s.ape_rmse_m).c_str() : "-",
                  ratio ? f("%.2fx", s.ape_rmse_m / off->summary.ape_rmse_m).c_str() : "-",
                  s.tracked, s.frames, s.frame_to_frame, s.bridged, s.lost);
    }

    if (seeds > 1) {
      // Per scene and mode over the draws: the median, and the range a single run could land
      // anywhere in.
      std::printf("\n## Accuracy over %d draws of each world (APE RMSE, metres)\n\n", seeds);
      std::printf("| scene | mode | median | min | max | lost frames (median) |\n");
      std::printf("|---|---|---|---|---|---|\n");
      std::vector<std::tuple<std::string, bool, std::string>> groups;
      for (const RunResult& r : runs) {
        const auto key = std::make_tuple(r.scenario, r.movers, r.mode.name);
        if (std::find(groups.begin(), groups.end(), key) == groups.end()) groups.push_back(key);
      }
      for (const auto& [scenario, movers, mode] : groups) {
        std::vector<double> ape, lost;
        std::vector<long long> drawn;
        for (const RunResult& r : runs) {
          if (r.scenario != scenario || r.movers != movers || r.mode.name != mode) continue;
          drawn.push_back(r.seed);
          lost.push_back(static_cast<double>(r.summary.lost));
          if (r.summary.ape_rmse_m >= 0) ape.push_back(r.summary.ape_rmse_m);
        }
        if (ape.empty()) continue;
        const auto [lo, hi] = std::minmax_element(ape.begin(), ape.end());
        std::printf("| %s | %s | %.4f | %.4f | %.4f | %.0f |\n",
                    scene_name({scenario, movers, 0, {}}).c_str(), mode.c_str(), median(ape), *lo,
                    *hi, median(lost));
        j["accuracy_over_seeds"].push_back({{"scenario", scenario},
                                            {"movers", movers},
                                            {"mode", mode},
                                            {"seeds", drawn},
                                            {"ape_rmse_m", ape},
                                            {"ape_rmse_median_m", median(ape)},
                                            {"ape_rmse_min_m", *lo},
                                            {"ape_rmse_max_m", *hi}});
      }
    }

    std::printf("\n## Dynamic-feature removal (against the simulator's mover masks)\n\n");
    std::printf(
        "| scene | mode | dynamic removed | static kept | dynamic features | static features |\n");
    std::printf("|---|---|---|---|---|---|\n");
    for (const RunResult& r : runs) {
      const auto& c = r.summary.removal;
      if (!r.movers || !r.summary.has_truth_masks) continue;
      std::printf("| %s | %s | %.1f%% | %.1f%% | %zu | %zu |\n",
                  scene_name({r.scenario, r.movers, 0, {}, r.seed}).c_str(), r.mode.name.c_str(),
                  c.removed_percent(), c.kept_percent(), c.dynamic_total, c.static_total);
    }

    // Objects from the run's own poses and detector, against the world (issue 6's figures
    // with SLAM in the loop; the objects area has them on truth poses and boxes).
    std::printf(
        "\n## Objects from the runs (SLAM poses, the mode's detector; against the world)\n\n");
    std::printf(
        "| scene | mode | recall | precision | centre err median (m) | size err median | class "
        "correct |\n|---|---|---|---|---|---|---|\n");
    for (const RunResult& r : runs) {
      if (!r.summary.objects || r.mode.detector == "none") continue;
      const kestrel::eval::ObjectScores& o = *r.summary.objects;
      std::printf("| %s | %s | %.2f (%d/%d) | %.2f (%d reported) | %.3f | %.3f | %.2f |\n",
                  scene_name({r.scenario, r.movers, 0, {}, r.seed}).c_str(), r.mode.name.c_str(),
                  o.recall, o.matched, o.truth, o.precision, o.reported, o.center_error_median,
                  o.size_error_median, o.class_correct);
      j["objects"].push_back({{"scenario", r.scenario},
                              {"movers", r.movers},
                              {"seed", r.seed},
                              {"mode", r.mode.name},
                              {"truth", o.truth},
                              {"reported", o.reported},
                              {"matched", o.matched},
                              {"recall", o.recall},
                              {"precision", o.precision},
                              {"center_error_median_m", o.center_error_median},
                              {"size_error_median", o.size_error_median},
                              {"class_correct", o.class_correct}});
    }

    std::printf(
        "\n## Output files (written after each hybrid+yolo run, as kestrel run --out writes "
        "them)\n\n| scene | seconds of data | files | MiB | written in (s) |\n"
        "|---|---|---|---|---|\n");
    for (const RunResult& r : runs) {
      if (r.summary.outputs_write_s < 0) continue;
      const double mib = static_cast<double>(r.summary.outputs_bytes) / (1024.0 * 1024.0);
      const double data_s = r.summary.trajectory.empty() ? 0.0
                                                         : r.summary.trajectory.stamps.back() -
                                                               r.summary.trajectory.stamps.front();
      std::printf("| %s | %.0f | %zu | %.1f | %.2f |\n",
                  scene_name({r.scenario, r.movers, 0, {}, r.seed}).c_str(), data_s,
                  r.summary.outputs_files, mib, r.summary.outputs_write_s);
      j["outputs"].push_back({{"scenario", r.scenario},
                              {"movers", r.movers},
                              {"seed", r.seed},
                              {"mode", r.mode.name},
                              {"data_s", data_s},
                              {"files", r.summary.outputs_files},
                              {"bytes", r.summary.outputs_bytes},
                              {"write_s", r.summary.outputs_write_s}});
    }
    std::printf("\nGoal (objects and maps issue): a 60 s run's files written in 2 s or less.\n");

    // Per-stage medians: the median over scenes of each run's per-frame median.
    const std::vector<std::string> stage_names = {"features", "dynamic_filter", "tracking",
                                                  "detection", "frame_latency"};
    std::printf("\n## Per-stage speed (ms per frame; median over scenes of per-frame medians)\n\n");
    // frame_latency stays in the JSON only: in lock-step runs it is mostly time spent queued.
    std::printf(
        "| mode | features | dynamic_filter | tracking | detection | tracking FPS | speed vs off "
        "|\n|---|---|---|---|---|---|---|\n");
    for (const Mode& mode : all_modes()) {
      std::map<std::string, std::vector<double>> per_stage;
      std::vector<double> tracking_ms, ratio;
      for (const RunResult& r : runs) {
        if (r.mode.name != mode.name) continue;
        for (const std::string& st : stage_names) per_stage[st].push_back(stage_p50(r.summary, st));
        tracking_ms.push_back(r.summary.tracking_ms_median);
        if (const RunResult* off = off_of(r); off && r.summary.tracking_ms_median > 0) {
          ratio.push_back(off->summary.tracking_ms_median / r.summary.tracking_ms_median);
        }
      }
      if (tracking_ms.empty()) continue;
      const double tm = median(tracking_ms);
      std::printf("| %s | %.1f | %.1f | %.1f | %s | %.1f | %.2fx |\n", mode.name.c_str(),
                  median(per_stage["features"]), median(per_stage["dynamic_filter"]),
                  median(per_stage["tracking"]),
                  mode.detector == "none" ? "-" : f("%.2f", median(per_stage["detection"])).c_str(),
                  tm > 0 ? 1000.0 / tm : 0.0, median(ratio));
      json m;
      for (const std::string& st : stage_names) m["stage_p50_ms"][st] = median(per_stage[st]);
      m["tracking_ms_median"] = tm;
      m["tracking_fps"] = tm > 0 ? 1000.0 / tm : 0.0;
      m["speed_vs_off"] = median(ratio);
      j["speed"][mode.name] = m;
    }

    std::printf("\n## Detector speed (alone, on %s frames)\n\n",
                rendered.front().scene.scenario.c_str());
    // The fastest frame beside the median: on a shared host the median moves with the
    // neighbours' load by a third (YOLO v1.1 4.6-6.4 ms within one day), the fastest much less.
    std::printf(
        "| detector | frames | median (ms) | p90 (ms) | fastest (ms) | FPS (median) |\n"
        "|---|---|---|---|---|---|\n");
    for (const auto& [name, ms] : detector_ms) {
      const double p50 = median(ms), p90 = kestrel::pipeline::percentile(ms, 90.0);
      const double fastest = ms.empty() ? 0.0 : *std::min_element(ms.begin(), ms.end());
      std::printf("| %s | %zu | %.2f | %.2f | %.2f | %.1f |\n", name.c_str(), ms.size(), p50, p90,
                  fastest, p50 > 0 ? 1000.0 / p50 : 0.0);
      j["detectors"][name] = {{"frames", ms.size()},
                              {"median_ms", p50},
                              {"p90_ms", p90},
                              {"min_ms", fastest},
                              {"fps", p50 > 0 ? 1000.0 / p50 : 0.0}};
    }

    std::printf("\n## Simulator\n\n| scene | frames | render FPS |\n|---|---|---|\n");
    for (const SceneResult& sr : rendered) {
      std::printf("| %s | %d | %.1f |\n", scene_name(sr.scene).c_str(), sr.frames, sr.render_fps);
    }
  }

  for (const RunResult& r : runs) {
    json run = json::parse(kestrel::pipeline::summary_json(r.summary));
    run["scenario"] = r.scenario;
    run["movers"] = r.movers;
    run["seed"] = r.seed;
    run["mode"] = r.mode.name;
    run["detector"] = r.mode.detector;
    run["dynamic"] = kestrel::dynamic::to_string(r.mode.dynamic);
    run["sensor"] = r.mode.sensor;
    run["oracle_false_negative_rate"] = r.mode.false_negative_rate;
    for (const auto& [stage, l] : r.summary.stages) {
      run["stages"][stage] = {{"count", l.count}, {"p50_ms", l.p50_ms}, {"p90_ms", l.p90_ms}};
    }
    run["counters"] = r.summary.counters;
    j["runs"].push_back(run);
  }

  // The other areas, each through the library that owns its figures (apps/bench_*.cpp).
  kestrel::bench::AreaOptions area;
  area.quick = flags.quick;
  area.tiny = flags.tiny;
  area.shared_data = kestrel::sim::default_assets_dir();
  area.work_dir = flags.work_dir;
  if (want("dynamic")) j["dynamic"] = kestrel::bench::bench_dynamic(area);
  if (want("evaluation")) j["evaluation"] = kestrel::bench::bench_evaluation(area);
  if (want("imu")) j["imu"] = kestrel::bench::bench_imu(area);
  if (want("objects")) j["objects"] = kestrel::bench::bench_objects(area);
  if (want("telemetry")) j["telemetry"] = kestrel::bench::bench_telemetry(area);
  if (want("video")) j["video"] = kestrel::bench::bench_video(area);
  if (want("endurance")) j["endurance"] = kestrel::bench::bench_endurance(area);

  const double total_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  j["wall_seconds"] = total_s;
  if (want("memory")) {
    // Peak resident set of this process over every area above (Linux reports KiB).
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    const double peak_mib = static_cast<double>(ru.ru_maxrss) / 1024.0;
    std::printf(
        "\n## Memory\n\n| peak RSS after the bench (MiB) | wall (s) |\n|---|---|\n"
        "| %.1f | %.0f |\n",
        peak_mib, total_s);
    j["memory"] = {{"peak_rss_mib", peak_mib}};
  }

  const std::string out =
      flags.json_path.empty() ? default_json_path(flags.quick, flags.only) : flags.json_path;
  if (const fs::path parent = fs::path(out).parent_path(); !parent.empty()) {
    fs::create_directories(parent);
  }
  std::ofstream(out) << j.dump(2) << "\n";
  if (!fs::exists(out)) throw kestrel::Error::at(out, 0, "--json", "cannot write the results");
  if (!flags.keep && flags.work_dir.empty()) fs::remove_all(work);
  std::printf("\nbench finished in %.0f s; results in %s\n", total_s, out.c_str());
}

void setup_bench(CLI::App& app) {
  auto flags = std::make_shared<BenchFlags>();
  auto* cmd = app.add_subcommand(
      "bench", "Benchmark accuracy, dynamic removal and speed on the synthetic scenarios");
  cmd->add_flag("--quick", flags->quick, "short scenes, fewer of them (under 5 minutes)");
  cmd->add_option(
      "--json", flags->json_path,
      "results file (default bench/results/{quick,full}-DATE.json, the areas' names for --only)");
  cmd->add_option("--work", flags->work_dir, "where the rendered scenes go (kept)");
  cmd->add_flag("--keep", flags->keep, "keep the rendered scenes in the temporary folder");
  cmd->add_flag("--tiny", flags->tiny, "the smallest inputs (seconds; for tests, not figures)");
  cmd->add_option("--seeds", flags->seeds,
                  "draws of each accuracy scene's world (default 1 with --quick, else 3); with "
                  "more than one, a table of each scene's median and range")
      ->check(CLI::Range(1, 20));
  cmd->add_option("--only", flags->only,
                  "areas to run: accuracy, dynamic, evaluation, imu, objects, telemetry, video, "
                  "endurance, memory")
      ->delimiter(',');
  // `kestrel bench dynamic` is `kestrel bench --only dynamic`.
  cmd->add_option("areas", flags->only, "areas to run (as --only)");
  cmd->callback([flags] { run_bench(*flags); });
}

}  // namespace

KESTREL_COMMAND(80, setup_bench);
