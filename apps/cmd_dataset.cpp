// `kestrel dataset info SPEC`: what a dataset holds (description, frame and IMU counts, time
// span, calibration). `--check` decodes every frame, so a broken file shows up before a run.
#include <cstdio>
#include <memory>
#include <string>

#include "apps/commands.hpp"
#include "core/config.hpp"
#include "io/dataset.hpp"
#include "io/indexed_source.hpp"

namespace {

using namespace kestrel;

struct InfoArgs {
  std::string spec;
  std::string config;
  bool check = false;
};

void run_info(const InfoArgs& a) {
  io::DatasetOptions options;
  options.config_file = a.config;
  const std::unique_ptr<io::MeasurementSource> src = io::open_dataset(a.spec, options);
  std::printf("%s\n", src->describe().c_str());
  std::printf("frames: %zu\n", src->frame_count());
  if (const auto* indexed = dynamic_cast<const io::IndexedSource*>(src.get())) {
    std::printf("imu samples: %zu\n", indexed->imu_count());
    if (const auto span = indexed->time_span()) {
      std::printf("time span: %s .. %s s (%.3f s)\n", format_seconds(span->first).c_str(),
                  format_seconds(span->second).c_str(), to_seconds(span->second - span->first));
    }
  }
  if (const auto gt = src->ground_truth()) {
    std::printf("ground truth: %zu poses", gt->size());
    if (!gt->empty()) std::printf(", %.6f .. %.6f s", gt->stamps.front(), gt->stamps.back());
    std::printf("\n");
  } else {
    std::printf("ground truth: none\n");
  }
  std::printf("calibration:\n%s", to_yaml(src->calibration()).c_str());
  if (a.check) {
    std::size_t frames = 0, imu = 0;
    while (const auto m = src->next()) {
      if (std::holds_alternative<ImuSample>(*m)) {
        ++imu;
      } else {
        ++frames;
      }
    }
    std::printf("check: decoded %zu frames, %zu IMU samples: all readable\n", frames, imu);
  }
}

void setup_dataset(CLI::App& app) {
  auto* cmd = app.add_subcommand("dataset",
                                 "Inspect datasets (TUM RGB-D, EuRoC, TUM-VI, OpenLORIS, Kestrel)");
  cmd->require_subcommand(1);
  auto args = std::make_shared<InfoArgs>();
  auto* info = cmd->add_subcommand("info", "Describe a dataset: counts, time span, calibration");
  info->add_option("SPEC", args->spec, "[tum:|euroc:|tumvi:|openloris:|kestrel:]DIR")->required();
  info->add_option("--config", args->config, "calibration file overriding the dataset's own")
      ->check(CLI::ExistingFile);
  info->add_flag("--check", args->check, "decode every frame to find unreadable files");
  info->callback([args] { run_info(*args); });
}

}  // namespace

KESTREL_COMMAND(300, setup_dataset);
