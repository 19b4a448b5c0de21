// `kestrel run` (one dataset through the whole system) and `kestrel demo` (the main job on the
// embedded default scene: render it, run with and without dynamic rejection, compare).
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "apps/commands.hpp"
#include "core/error.hpp"
#include "io/dataset.hpp"
#include "pipeline/run_job.hpp"
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
  std::string detector = "yolo";
  std::string dynamic = "hybrid";
  bool realtime = false;
};

std::string dataset_dir_of(const std::string& spec) {
  const auto colon = spec.find(':');
  const std::string dir = colon == std::string::npos ? spec : spec.substr(colon + 1);
  return std::filesystem::exists(dir + "/boxes.csv") ? dir : "";
}

void print_summary(const char* name, const RunSummary& s) {
  std::printf("%s: %zu frames, %zu tracked, %zu lost", name, s.frames, s.tracked, s.lost);
  if (s.ape_rmse_m >= 0) std::printf(", APE RMSE %.4f m (%zu pairs)", s.ape_rmse_m, s.ape_pairs);
  std::printf("\n");
  if (s.has_truth_masks) {
    std::printf("  dynamic features removed %.1f%% (%zu), static kept %.1f%% (%zu)\n",
                s.removal.removed_percent(), s.removal.dynamic_total, s.removal.kept_percent(),
                s.removal.static_total);
  }
  std::printf("  tracking %.1f ms/frame median (%.0f FPS), detector %.1f ms/frame\n",
              s.tracking_ms_median, s.tracking_ms_median > 0 ? 1000.0 / s.tracking_ms_median : 0.0,
              s.detector_ms_median);
}

void setup_run(CLI::App& app) {
  auto flags = std::make_shared<RunFlags>();
  auto* cmd = app.add_subcommand("run", "Run the SLAM system over a dataset");
  cmd->add_option("--dataset", flags->dataset,
                  "tum:DIR | euroc:DIR | tumvi:DIR | openloris:DIR | kestrel:DIR (or a DIR)")
      ->required();
  cmd->add_option("--out", flags->out, "output folder (trajectory.txt, timing.json, summary.json)")
      ->required();
  cmd->add_option("--config", flags->config, "calibration / settings YAML")
      ->check(CLI::ExistingFile);
  cmd->add_option("--detector", flags->detector, "yolo | oracle | none")
      ->check(CLI::IsMember({"yolo", "oracle", "none"}));
  cmd->add_option("--dynamic", flags->dynamic, "hybrid | detection | geometry | off")
      ->check(CLI::IsMember({"hybrid", "detection", "geometry", "off"}));
  cmd->add_flag("--realtime", flags->realtime,
                "threads run free (detection may lag and drop) instead of in lock-step");
  cmd->callback([flags] {
    kestrel::io::DatasetOptions dopt;
    dopt.config_file = flags->config;
    auto source = kestrel::io::open_dataset(flags->dataset, dopt);
    std::printf("kestrel run: %s\n", source->describe().c_str());
    RunOptions opt;
    opt.dataset_dir = dataset_dir_of(flags->dataset);
    opt.detector = flags->detector;
    opt.dynamic = *kestrel::dynamic::filter_mode_from_string(flags->dynamic);
    opt.sequential = !flags->realtime;
    opt.out_dir = flags->out;
    print_summary("run", kestrel::pipeline::run_sequence(*source, opt));
    std::printf("outputs in %s\n", flags->out.c_str());
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
    const auto rec = kestrel::sim::record_sequence(sim, seq);
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
      opt.detector = i == 0 ? flags->detector : "none";
      opt.dynamic = modes[i];
      opt.out_dir = flags->out + "/" + names[i];
      results[i] = kestrel::pipeline::run_sequence(*source, opt);
    }
    std::printf(
        "\n| rejection | APE RMSE (m) | dynamic removed | static kept | tracking FPS | "
        "detector FPS | lost |\n|---|---|---|---|---|---|---|\n");
    for (int i = 0; i < 2; ++i) {
      const RunSummary& s = results[i];
      std::printf("| %s | %.4f | %.1f%% | %.1f%% | %.0f | %s | %zu |\n", names[i], s.ape_rmse_m,
                  s.removal.removed_percent(), s.removal.kept_percent(),
                  s.tracking_ms_median > 0 ? 1000.0 / s.tracking_ms_median : 0.0,
                  s.detector_ms_median > 0
                      ? std::to_string(static_cast<int>(1000.0 / s.detector_ms_median)).c_str()
                      : "-",
                  s.lost);
    }
    std::printf("\noutputs in %s/ (hybrid/, off/: trajectory.txt, timing.json, summary.json)\n",
                flags->out.c_str());
  });
}

}  // namespace

KESTREL_COMMAND(50, setup_run);
KESTREL_COMMAND(5, setup_demo);
