// `kestrel run` (one dataset through the whole system) and `kestrel demo` (the main job on the
// embedded default scene: render it, run with and without dynamic rejection, compare).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>

#include "apps/commands.hpp"
#include "core/error.hpp"
#include "detect/box_coasting.hpp"
#include "eval/report/run_report.hpp"
#include "io/dataset.hpp"
#include "io/image_io.hpp"
#include "io/kestrel_sequence.hpp"
#include "maps/grid_io.hpp"
#include "pipeline/progress.hpp"
#include "pipeline/run_job.hpp"
#include "sim/builtin_scenarios.hpp"
#include "sim/live_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"

namespace {

using kestrel::pipeline::RunOptions;
using kestrel::pipeline::RunSummary;

struct RunFlags {
  std::string dataset;
  std::string out;
  std::string config;
  std::string load_map;
  std::string detector = "yolo";
  std::string yolo_model = kestrel::detect::to_string(kestrel::detect::kPipelineYoloModel);
  std::string dynamic = "hybrid";
  std::string mode = "auto";
  bool no_loop = false;
  bool triangulate = true;
  bool half_resolution_flow = false;
  double flow_skip_gate_px = -1.0;  // unset: the filter's default
  bool inertial_ba = false;
  bool no_gyro_prior = false;
  bool no_depth_carry = false;
  bool no_corner_tracks = false;
  bool no_park = false;
  int carry_boxes = kestrel::detect::BoxCoastOptions{}.max_frames;
  int mover_budget_margin = kestrel::pipeline::SystemOptions{}.mover_budget_margin_px;
  int mover_silhouette = kestrel::pipeline::SystemOptions{}.mover_silhouette.grow_px;
  bool realtime = false;
  int max_in_flight = 2;
  double dense_map_interval = kestrel::pipeline::SystemOptions{}.dense_map_interval_s;
  double duration = -1.0;  // sim: scenes only
  bool no_movers = false;  // sim: scenes only
};

std::string dataset_dir_of(const std::string& spec) {
  const auto colon = spec.find(':');
  const std::string dir = colon == std::string::npos ? spec : spec.substr(colon + 1);
  return std::filesystem::exists(dir + "/boxes.csv") ? dir : "";
}

// The command line exactly as typed (CLI11 does not keep argv; Linux does).
std::string command_line() {
  std::ifstream f("/proc/self/cmdline", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  std::string out;
  std::string arg;
  for (char c : all) {
    if (c != '\0') {
      arg += c;
      continue;
    }
    const bool quote = arg.empty() || arg.find_first_of(" \t'\"$") != std::string::npos;
    out += (out.empty() ? "" : " ") + (quote ? "'" + arg + "'" : arg);
    arg.clear();
  }
  return out;
}

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// One run in the report's terms.
kestrel::report::RunRecord record_of(const std::string& name, const std::string& description,
                                     const RunSummary& s) {
  kestrel::report::RunRecord r;
  r.name = name;
  r.description = description;
  r.estimate = s.trajectory;
  r.frames = s.frames, r.tracked = s.tracked, r.lost = s.lost;
  r.has_removal = s.has_truth_masks;
  r.dynamic_total = s.removal.dynamic_total, r.dynamic_removed = s.removal.dynamic_removed;
  r.static_total = s.removal.static_total, r.static_kept = s.removal.static_kept;
  r.tracking_ms_median = s.tracking_ms_median;
  r.detector_ms_median = s.detector_ms_median;
  r.wall_seconds = s.wall_seconds;
  for (const auto& [stage, l] : s.stages)
    r.stages.push_back({stage, l.count, l.p50_ms, l.p90_ms, l.max_ms});
  r.counters = s.counters;
  for (const auto& m : s.memory) r.memory_mib.emplace_back(m.stream_s, m.rss_mib);
  return r;
}

// The kept frames with the detector's boxes, every feature (static or rejected as dynamic) and
// the ground-truth boxes of movers at their stamps.
std::vector<kestrel::report::StripFrame> strip_of(const std::string& run_name, const RunSummary& s,
                                                  const std::string& dataset_dir) {
  std::vector<kestrel::io::SequenceBox> boxes;
  if (!dataset_dir.empty()) boxes = kestrel::io::read_boxes(dataset_dir + "/boxes.csv");
  // Stamps shown from the start of the run, as on the report's time axes.
  double t0 = 0.0;
  if (s.ground_truth && !s.ground_truth->empty()) {
    t0 = s.ground_truth->stamps.front();
  } else if (!s.trajectory.empty()) {
    t0 = s.trajectory.stamps.front();
  }
  std::vector<kestrel::report::StripFrame> out;
  for (const auto& k : s.strip) {
    kestrel::report::StripFrame f;
    f.image = k.frame.color;
    char caption[160];
    std::snprintf(caption, sizeof caption,
                  "%s · t = %.2f s · %s · %d features, %d rejected as dynamic, %d inliers",
                  run_name.c_str(), kestrel::to_seconds(k.frame.t) - t0,
                  kestrel::tracking::to_string(k.report.state), k.report.features,
                  k.report.dynamic_features, k.report.inliers);
    f.caption = caption;
    for (std::size_t i = 0; i < k.report.feature_px.size(); ++i) {
      f.points.push_back({k.report.feature_px[i].x(), k.report.feature_px[i].y(),
                          k.report.feature_dynamic[i] != 0});
    }
    for (const auto& b : k.report.boxes) {
      f.boxes.push_back({b.x_min, b.y_min, b.x_max, b.y_max, "detected", true});
    }
    // Movers and people only: the static furniture's boxes would hide the picture.
    for (const auto& b : boxes) {
      if (b.t == k.frame.t && (b.moving || b.label == "person"))
        f.boxes.push_back({b.x_min, b.y_min, b.x_max, b.y_max, b.label, b.moving});
    }
    out.push_back(std::move(f));
  }
  return out;
}

// The run's 2D grid with its objects, when the run wrote them (RGB-D runs do).
std::optional<kestrel::report::GridMap> grid_of(const std::string& dir) {
  namespace fs = std::filesystem;
  if (!fs::exists(dir + "/map.yaml") || !fs::exists(dir + "/map.pgm")) return std::nullopt;
  const auto meta = kestrel::maps::read_map_metadata(dir + "/map.yaml");
  kestrel::report::GridMap g;
  g.occupancy = kestrel::io::load_image(dir + "/map.pgm");
  g.resolution = meta.resolution;
  g.origin_x = meta.origin_x;
  g.origin_y = meta.origin_y;
  if (fs::exists(dir + "/objects.json")) {
    for (const auto& o : kestrel::io::read_objects(dir + "/objects.json")) {
      g.objects.push_back({o.label, o.center.x(), o.center.y()});
    }
  }
  return g;
}

std::string fmt_1(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

void print_summary(const char* name, const RunSummary& s) {
  std::printf("%s: %zu frames, ", name, s.frames);
  if (s.dropped > 0) std::printf("%zu dropped while the tracker was busy, ", s.dropped);
  std::printf("%zu tracked", s.tracked);
  std::string how;  // how the tracked frames without vision's own pose got theirs
  if (s.frame_to_frame > 0) {
    how += std::to_string(s.frame_to_frame) +
           " of them frame to frame: lost to the map, their step fixed by depth and corners";
  }
  if (s.bridged > 0) {
    how += (how.empty() ? "" : "; ") + std::to_string(s.bridged) +
           " bridged: the local map restarted there";
  }
  if (!how.empty()) std::printf(" (%s)", how.c_str());
  std::printf(", %zu lost", s.lost);
  if (s.depth_imu > 0) {
    std::printf(" (%zu of them aligned by depth with the IMU, %zu carried by the IMU alone)",
                s.depth_imu, s.inertial_only);
  } else if (s.inertial_only > 0) {
    std::printf(" (%zu of them carried by the IMU)", s.inertial_only);
  }
  if (s.ape_rmse_m >= 0) std::printf(", APE RMSE %.4f m (%zu pairs)", s.ape_rmse_m, s.ape_pairs);
  std::printf("\n");
  if (s.map_relocalized_after_s) {
    if (*s.map_relocalized_after_s >= 0) {
      std::printf("  relocalized in the loaded map %.2f s after the first frame\n",
                  *s.map_relocalized_after_s);
    } else {
      std::printf("  never relocalized in the loaded map\n");
    }
  }
  if (s.has_truth_masks) {
    std::printf("  dynamic features removed %.1f%% (%zu), static kept %.1f%% (%zu)\n",
                s.removal.removed_percent(), s.removal.dynamic_total, s.removal.kept_percent(),
                s.removal.static_total);
  }
  if (!s.objects_error.empty()) {
    std::printf("  objects not scored: %s\n", s.objects_error.c_str());
  }
  if (s.objects) {
    const kestrel::eval::ObjectScores& o = *s.objects;
    std::printf(
        "  objects against the world: recall %.2f (%d of %d), precision %.2f (%d reported), "
        "class correct %.2f, centre error median %.3f m, size error median %.0f%%\n",
        o.recall, o.matched, o.truth, o.precision, o.reported, o.class_correct,
        o.center_error_median, 100.0 * o.size_error_median);
  }
  std::printf("  tracking %.1f ms/frame median (%.0f FPS), detector %.1f ms/frame\n",
              s.tracking_ms_median, s.tracking_ms_median > 0 ? 1000.0 / s.tracking_ms_median : 0.0,
              s.detector_ms_median);
  if (auto it = s.stages.find("frame_latency"); it != s.stages.end()) {
    std::printf("  frame arrival to pose: p50 %.1f ms, p99 %.1f ms, max %.1f ms\n",
                it->second.p50_ms, it->second.p99_ms, it->second.max_ms);
  }
  if (!s.memory.empty()) {
    std::printf("  resident memory %.0f MiB at the end (peak %.0f MiB)\n", s.memory.back().rss_mib,
                kestrel::pipeline::peak_rss_mib(s.memory));
  }
  if (s.outputs_write_s >= 0) {
    std::printf("  outputs written in %.2f s (%zu files, %.1f MiB)\n", s.outputs_write_s,
                s.outputs_files, static_cast<double>(s.outputs_bytes) / (1024.0 * 1024.0));
  }
}

void setup_run(CLI::App& app) {
  auto flags = std::make_shared<RunFlags>();
  auto* cmd = app.add_subcommand("run", "Run the SLAM system over a dataset");
  cmd->add_option("--dataset", flags->dataset,
                  "tum:DIR | euroc:DIR | tumvi:DIR | openloris:DIR | kestrel:DIR (or a DIR) | "
                  "sim:SCENARIO (rendered live)")
      ->required();
  cmd->add_option("--out", flags->out,
                  "output folder (trajectory.txt, timing.json, summary.json, report.html)")
      ->required();
  cmd->add_option("--config", flags->config, "calibration / settings YAML")
      ->check(CLI::ExistingFile);
  cmd->add_option("--load-map", flags->load_map,
                  "map.bin of an earlier session: tracking starts lost and relocalizes in it "
                  "(multi-session); the run extends and saves that map")
      ->check(CLI::ExistingFile);
  cmd->add_option("--detector", flags->detector, "yolo | oracle | none")
      ->check(CLI::IsMember({"yolo", "oracle", "none"}));
  cmd->add_option("--yolo-model", flags->yolo_model,
                  "with --detector yolo: v1.1 (COCO), xl (COCO, larger; the default) or body "
                  "(persons)")
      ->check(CLI::IsMember({"v1.1", "xl", "body"}))
      ->capture_default_str();
  cmd->add_option("--dynamic", flags->dynamic, "hybrid | detection | geometry | off")
      ->check(CLI::IsMember({"hybrid", "detection", "geometry", "off"}));
  cmd->add_option("--mode", flags->mode,
                  "auto (the richest the dataset offers) | rgbd | rgbd-imu | stereo | stereo-imu")
      ->check(CLI::IsMember({"auto", "rgbd", "rgbd-imu", "stereo", "stereo-imu"}))
      ->capture_default_str();
  cmd->add_flag("--no-loop", flags->no_loop, "no loop closing (odometry and local map only)");
  cmd->add_flag("--triangulate,!--no-triangulate", flags->triangulate,
                "triangulate map points from two views where depth has none (beyond its range); "
                "on by default");
  cmd->add_flag("--inertial-ba", flags->inertial_ba,
                "visual-inertial local BA: keyframes joined by the IMU's pre-integration");
  cmd->add_flag("--no-depth-carry", flags->no_depth_carry,
                "frames features cannot track are carried by the IMU alone, not aligned by depth");
  cmd->add_flag("--no-corner-tracks", flags->no_corner_tracks,
                "depth carries the frames features cannot track without corners followed from the "
                "frame before (the IMU keeps the directions one plane's depth leaves open)");
  cmd->add_flag("--no-gyro-prior", flags->no_gyro_prior,
                "no gyro rotation prior in the per-frame pose optimization");
  cmd->add_flag("--no-park", flags->no_park,
                "vehicles are movers even when they stand still (no parked vehicles in the maps)");
  cmd->add_option("--carry-boxes", flags->carry_boxes,
                  "N: a mover's box is carried over up to N frames its detection misses, along its "
                  "image motion (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0, 30));
  cmd->add_option("--mover-budget", flags->mover_budget_margin,
                  "PX: features are picked apart in the last frame's mover boxes grown by PX, and "
                  "the scenery gets the whole feature budget of its own (-1: one budget)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 200));
  cmd->add_option("--mover-silhouette", flags->mover_silhouette,
                  "PX: no features where the last frame's movers were, pixel by pixel (their "
                  "boxes' depth at the object's, grown by PX; -1: off)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 100));
  cmd->add_flag("--half-res-flow", flags->half_resolution_flow,
                "the dynamic filter's flow on the half-resolution image: a quarter of the cost");
  cmd->add_option("--imu-vouched-flow", flags->flow_skip_gate_px,
                  "PX: no backward flow check for a forward flow that ends within PX of where the "
                  "IMU's motion puts the point (off by default)")
      ->check(CLI::Range(0.0, 10.0));
  cmd->add_flag("--realtime", flags->realtime,
                "as a live sensor: frames fed at their stamps' pace, threads run free (detection "
                "may lag and drop) instead of in lock-step");
  cmd->add_option("--max-in-flight", flags->max_in_flight,
                  "with --realtime: a frame arriving while this many are still being tracked is "
                  "dropped, as a live camera's would be (0: never drop; the source waits)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--dense-map-interval", flags->dense_map_interval,
                  "S: the dense maps (cloud, OctoMap, grid) take a keyframe at most every S "
                  "seconds of stream (0: every keyframe); the object database takes them all")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--duration", flags->duration, "seconds of a sim: scene (default: its own)");
  cmd->add_flag("--no-movers", flags->no_movers, "a sim: scene without its walkers and vehicles");
  cmd->callback([flags] {
    RunOptions opt;
    std::unique_ptr<kestrel::io::MeasurementSource> source;
    std::string scenario_yaml;
    if (flags->dataset.rfind("sim:", 0) == 0) {
      // The simulator as a live camera: nothing written, any length.
      if (!flags->config.empty()) {
        throw kestrel::Error("--config: a sim: scene carries its own calibration");
      }
      kestrel::sim::ScenarioOverrides over;
      over.duration = flags->duration;
      over.no_movers = flags->no_movers;
      auto live = std::make_unique<kestrel::sim::LiveSource>(
          kestrel::sim::load_scenario(flags->dataset.substr(4), over));
      const kestrel::sim::LiveSource* truth = live.get();
      scenario_yaml = live->simulator().scenario().yaml;
      opt.truth_masks = [truth](kestrel::Timestamp t) { return truth->truth_mask(t); };
      source = std::move(live);
    } else {
      if (flags->duration > 0 || flags->no_movers) {
        throw kestrel::Error("--duration and --no-movers apply to sim: scenes only");
      }
      kestrel::io::DatasetOptions dopt;
      dopt.config_file = flags->config;
      source = kestrel::io::open_dataset(flags->dataset, dopt);
      opt.dataset_dir = dataset_dir_of(flags->dataset);
    }
    std::printf("kestrel run: %s\n", source->describe().c_str());

    opt.detector = flags->detector;
    opt.yolo_model = *kestrel::detect::parse_yolo_model(flags->yolo_model);
    opt.dynamic = *kestrel::dynamic::filter_mode_from_string(flags->dynamic);
    opt.sequential = !flags->realtime;
    opt.paced = flags->realtime;
    opt.max_frames_in_flight = flags->max_in_flight;
    opt.memory_sample_s = 1.0;
    opt.out_dir = flags->out;
    opt.mode = flags->mode;
    opt.load_map = flags->load_map;
    opt.loop_closing = !flags->no_loop;
    opt.triangulate = flags->triangulate;
    opt.half_resolution_flow = flags->half_resolution_flow;
    opt.flow_skip_gate_px = flags->flow_skip_gate_px;
    opt.inertial_ba = flags->inertial_ba;
    opt.dense_map_interval_s = flags->dense_map_interval;
    opt.gyro_rotation_prior = !flags->no_gyro_prior;
    opt.depth_carry = !flags->no_depth_carry;
    opt.corner_tracks = !flags->no_corner_tracks;
    opt.park_vehicles = !flags->no_park;
    opt.carried_box_frames = flags->carry_boxes;
    opt.mover_budget_margin_px = flags->mover_budget_margin;
    opt.mover_silhouette_grow_px = flags->mover_silhouette;
    const RunSummary summary = kestrel::pipeline::run_sequence(*source, opt);
    print_summary("run", summary);
    kestrel::report::ReportInput report;
    report.command_line = command_line();
    if (!flags->config.empty()) {
      report.config_text = "# " + flags->config + "\n" + read_text(flags->config);
    } else if (!scenario_yaml.empty()) {
      report.config_text = "# " + flags->dataset + " (rendered live)\n" + scenario_yaml;
    } else if (!opt.dataset_dir.empty() &&
               std::filesystem::exists(opt.dataset_dir + "/calib.yaml")) {
      report.config_text = "# " + opt.dataset_dir + "/calib.yaml (no --config)\n" +
                           read_text(opt.dataset_dir + "/calib.yaml");
    } else {
      report.config_text = "(the dataset's own calibration; no --config)";
    }
    report.version = KESTREL_VERSION;
    report.dataset = source->describe();
    report.ground_truth = summary.ground_truth;
    report.runs.push_back(record_of(
        "run", "detector " + flags->detector + ", dynamic rejection " + flags->dynamic, summary));
    report.frames = strip_of("run", summary, opt.dataset_dir);
    report.grid = grid_of(flags->out);
    const std::string report_path = flags->out + "/report.html";
    kestrel::report::write_report(report, report_path);
    std::printf("outputs in %s\nreport: %s\n", flags->out.c_str(), report_path.c_str());
  });
}

struct DemoFlags {
  std::string out = "demo-out";
  std::string scenario = "cafe";
  double duration = 30.0;
  std::string detector = "yolo";
};

void setup_demo(CLI::App& app) {
  auto flags = std::make_shared<DemoFlags>();
  auto* cmd = app.add_subcommand(
      "demo", "Render a dynamic scene, run Kestrel with and without dynamic rejection, compare");
  cmd->add_option("--out", flags->out, "output folder")->capture_default_str();
  cmd->add_option("--scenario", flags->scenario, "built-in scenario or YAML file")
      ->capture_default_str();
  cmd->add_option("--duration", flags->duration, "seconds of the scene to render")
      ->check(CLI::Range(1.0, 600.0))
      ->capture_default_str();
  cmd->add_option("--detector", flags->detector, "yolo | oracle | none")
      ->check(CLI::IsMember({"yolo", "oracle", "none"}))
      ->capture_default_str();
  cmd->callback([flags] {
    namespace fs = std::filesystem;
    const std::string seq = flags->out + "/sequence";
    fs::create_directories(flags->out);
    kestrel::sim::ScenarioOverrides over;
    over.duration = flags->duration;
    kestrel::sim::Simulator sim(kestrel::sim::load_scenario(flags->scenario, over));
    std::printf("kestrel demo: rendering '%s' (%d frames) into %s\n", flags->scenario.c_str(),
                sim.frame_count(), seq.c_str());
    fs::remove_all(seq);
    kestrel::pipeline::ProgressBar bar(static_cast<std::size_t>(sim.frame_count()), "frames");
    const auto rec = kestrel::sim::record_sequence(sim, seq, [&bar](int done, int) {
      bar.update(static_cast<std::size_t>(done), "rendering");
    });
    std::printf("  rendered %d frames at %.1f FPS; movers cover >= 25%% of the image in %d\n",
                rec.frames, rec.frames / std::max(rec.render_seconds, 1e-9),
                rec.frames_with_quarter_movers);

    RunSummary results[2];
    const char* names[2] = {"hybrid", "off"};
    const kestrel::dynamic::FilterMode modes[2] = {kestrel::dynamic::FilterMode::kHybrid,
                                                   kestrel::dynamic::FilterMode::kOff};
    for (int i = 0; i < 2; ++i) {
      std::printf("running with dynamic rejection %s (detector %s)\n", names[i],
                  i == 0 ? flags->detector.c_str() : "none");
      auto source = kestrel::io::open_dataset("kestrel:" + seq);
      RunOptions opt;
      opt.dataset_dir = seq;
      opt.memory_sample_s = 1.0;
      opt.detector = i == 0 ? flags->detector : "none";
      opt.dynamic = modes[i];
      opt.out_dir = flags->out + "/" + names[i];
      results[i] = kestrel::pipeline::run_sequence(*source, opt);
    }
    kestrel::report::ReportInput report;
    report.title = "Kestrel demo: dynamic rejection on against off";
    report.command_line = command_line();
    if (const char* yaml = kestrel::sim::builtin_scenario(flags->scenario)) {
      report.config_text = "# built-in scenario '" + flags->scenario + "', duration " +
                           std::to_string(flags->duration) + " s\n" + yaml;
    } else {
      report.config_text = "# " + flags->scenario + "\n" + read_text(flags->scenario);
    }
    report.version = KESTREL_VERSION;
    report.dataset = "kestrel:" + seq;
    report.ground_truth = results[0].ground_truth;
    report.notes.push_back("The same rendered scene is run twice: with the " + flags->detector +
                           " detector and hybrid dynamic rejection, and with rejection off.");
    for (int i = 0; i < 2; ++i) {
      report.runs.push_back(record_of(names[i],
                                      std::string("detector ") +
                                          (i == 0 ? flags->detector : "none") + ", rejection " +
                                          names[i],
                                      results[i]));
    }
    report.frames = strip_of(names[0], results[0], seq);
    report.grid = grid_of(flags->out + "/" + names[0]);
    const std::string report_path = flags->out + "/report.html";
    kestrel::report::write_report(report, report_path);
    std::printf(
        "\n| rejection | APE RMSE (m) | dynamic removed | static kept | tracking FPS | "
        "detector FPS | lost | objects found | objects: recall / precision |\n"
        "|---|---|---|---|---|---|---|---|---|\n");
    for (int i = 0; i < 2; ++i) {
      const RunSummary& s = results[i];
      // The objects the run wrote (objects.json): none without a detector.
      const std::string objects_path = flags->out + "/" + names[i] + "/objects.json";
      const std::size_t objects =
          fs::exists(objects_path) ? kestrel::io::read_objects(objects_path).size() : 0;
      // One decimal everywhere, so the printed figures can be checked against summary.json.
      // Against the rendered world (pipeline/sequence_object_truth.hpp).
      std::string scored = "-";
      if (s.objects) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.2f (%d of %d) / %.2f", s.objects->recall,
                      s.objects->matched, s.objects->truth, s.objects->precision);
        scored = buf;
      }
      std::printf("| %s | %.4f | %.1f%% | %.1f%% | %.1f | %s | %zu | %zu | %s |\n", names[i],
                  s.ape_rmse_m, s.removal.removed_percent(), s.removal.kept_percent(),
                  s.tracking_ms_median > 0 ? 1000.0 / s.tracking_ms_median : 0.0,
                  s.detector_ms_median > 0 ? fmt_1(1000.0 / s.detector_ms_median).c_str() : "-",
                  s.lost, objects, scored.c_str());
    }
    std::printf(
        "\noutputs in %s/ (hybrid/, off/: trajectory.txt, timing.json, summary.json, objects.json, "
        "map.pgm + map.yaml, octomap.bt, cloud.ply)\n",
        flags->out.c_str());
    std::printf("report: %s\n", report_path.c_str());
  });
}

}  // namespace

KESTREL_COMMAND(50, setup_run);
KESTREL_COMMAND(5, setup_demo);
