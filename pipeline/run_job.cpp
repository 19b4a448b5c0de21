#include "pipeline/run_job.hpp"

#include <unistd.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/error.hpp"
#include "detect/oracle_detector.hpp"
#include "detect/yolo_fastest.hpp"
#include "eval/trajectory_evaluation.hpp"
#include "io/kestrel_sequence.hpp"
#include "io/trajectory_io.hpp"
#include "pipeline/system.hpp"

namespace kestrel::pipeline {
namespace {

io::PoseSeries to_series(const Trajectory& t) {
  io::PoseSeries s;
  s.stamps = t.stamps;
  for (const SE3& p : t.poses) s.poses.push_back(p.matrix());
  return s;
}

// A one-line progress display: a bar with rate and time left on a terminal, plain lines
// every 10% otherwise (CI logs).
class Progress {
 public:
  Progress(std::size_t total, bool enabled) : total_(total), enabled_(enabled), tty_(isatty(1)) {}
  void update(std::size_t done, const char* state) {
    if (!enabled_ || total_ == 0) return;
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double fps = secs > 0 ? done / secs : 0.0;
    const double left = fps > 0 ? (total_ - done) / fps : 0.0;
    if (tty_) {
      const int width = 30;
      const int filled = static_cast<int>(width * done / total_);
      std::printf("\r  [%.*s%*s] %zu/%zu %5.1f FPS %4.0fs left  %-12s", filled,
                  "##############################", width - filled, "", done, total_, fps, left,
                  state);
      if (done == total_) std::printf("\n");
      std::fflush(stdout);
    } else if (done * 10 / total_ != last_decile_ || done == total_) {
      last_decile_ = done * 10 / total_;
      std::printf("  %zu/%zu frames, %.1f FPS, %s\n", done, total_, fps, state);
      std::fflush(stdout);
    }
  }

 private:
  std::size_t total_;
  bool enabled_, tty_;
  std::size_t last_decile_ = 0;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

class ProgressObserver : public Observer {
 public:
  explicit ProgressObserver(Progress& p) : progress_(p) {}
  void on_frame(const FrameReport& r) override {
    progress_.update(++done_, tracking::to_string(r.state));
  }

 private:
  Progress& progress_;
  std::size_t done_ = 0;
};

}  // namespace

RunSummary run_sequence(io::MeasurementSource& source, const RunOptions& options) {
  std::unique_ptr<detect::Detector> detector;
  if (options.detector == "yolo") {
    const std::string dir =
        options.models_dir.empty() ? detect::find_models_dir() : options.models_dir;
    detector = std::make_unique<detect::YoloFastest>(dir);
  } else if (options.detector == "oracle") {
    if (options.dataset_dir.empty()) {
      throw Error("--detector oracle needs a Kestrel sequence with boxes.csv");
    }
    detector = std::make_unique<detect::OracleDetector>(
        io::read_boxes(options.dataset_dir + "/boxes.csv"));
  } else if (options.detector != "none") {
    throw Error("unknown detector '" + options.detector + "' (yolo, oracle or none)");
  }

  SystemOptions sys_opt;
  sys_opt.sequential = options.sequential;
  sys_opt.dynamic.mode = options.dynamic;
  System system(source.calibration(), sys_opt, std::move(detector));
  RunSummary summary;
  if (!options.dataset_dir.empty() && std::filesystem::exists(options.dataset_dir + "/dynamic")) {
    summary.has_truth_masks = true;
    const std::string dir = options.dataset_dir;
    system.set_truth_masks([dir](Timestamp t) { return io::read_dynamic_mask(dir, t); });
  }
  Progress progress(source.frame_count(), options.progress);
  ProgressObserver progress_observer(progress);
  system.add_observer(&progress_observer);

  const auto t0 = std::chrono::steady_clock::now();
  while (auto m = source.next()) {
    system.feed(*m);
    if (!std::holds_alternative<ImuSample>(*m)) ++summary.frames;
  }
  system.finish();
  summary.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const Trajectory traj = system.trajectory();
  summary.tracked = traj.size();
  summary.lost = system.frames_lost();
  summary.removal = system.removal();
  const auto stages = system.stats().summaries();
  double per_frame = 0.0;
  for (const char* s : {"features", "dynamic_filter", "tracking"}) {
    if (auto it = stages.find(s); it != stages.end()) per_frame += it->second.p50_ms;
  }
  summary.tracking_ms_median = per_frame;
  if (auto it = stages.find("detection"); it != stages.end()) {
    summary.detector_ms_median = it->second.p50_ms;
  }
  summary.timing_json = system.stats().to_json();

  if (const auto gt = source.ground_truth(); gt && !gt->empty() && traj.size() >= 3) {
    eval::ApeOptions ape;
    ape.association.method = eval::AssociationMethod::kEvo;
    ape.association.max_diff = 0.01;
    ape.alignment = eval::Alignment::kSe3;
    const eval::Evaluation e = eval::evaluate_ape(to_series(*gt), to_series(traj), ape);
    summary.ape_rmse_m = e.stats.rmse;
    summary.ape_pairs = e.stats.count;
  }

  if (!options.out_dir.empty()) {
    std::filesystem::create_directories(options.out_dir);
    io::write_tum(options.out_dir + "/trajectory.txt", traj);
    std::ofstream(options.out_dir + "/timing.json") << summary.timing_json << "\n";
    std::ofstream(options.out_dir + "/summary.json") << summary_json(summary) << "\n";
  }
  return summary;
}

std::string summary_json(const RunSummary& s) {
  nlohmann::json j;
  j["frames"] = s.frames;
  j["tracked"] = s.tracked;
  j["lost"] = s.lost;
  j["ape_rmse_m"] = s.ape_rmse_m;
  j["ape_pairs"] = s.ape_pairs;
  if (s.has_truth_masks) {
    j["dynamic_removed_percent"] = s.removal.removed_percent();
    j["static_kept_percent"] = s.removal.kept_percent();
    j["dynamic_features"] = s.removal.dynamic_total;
    j["static_features"] = s.removal.static_total;
  }
  j["tracking_ms_median"] = s.tracking_ms_median;
  j["tracking_fps"] = s.tracking_ms_median > 0 ? 1000.0 / s.tracking_ms_median : 0.0;
  j["detector_ms_median"] = s.detector_ms_median;
  j["detector_fps"] = s.detector_ms_median > 0 ? 1000.0 / s.detector_ms_median : 0.0;
  j["wall_seconds"] = s.wall_seconds;
  return j.dump(2);
}

}  // namespace kestrel::pipeline
