#include "pipeline/run_job.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <thread>

#include "core/error.hpp"
#include "detect/oracle_detector.hpp"
#include "detect/yolo_fastest.hpp"
#include "eval/trajectory_evaluation.hpp"
#include "io/kestrel_sequence.hpp"
#include "io/trajectory_io.hpp"
#include "pipeline/live_feed.hpp"
#include "pipeline/process_memory.hpp"
#include "pipeline/progress.hpp"
#include "pipeline/sequence_object_truth.hpp"
#include "pipeline/system.hpp"

namespace kestrel::pipeline {
namespace {

// Shows progress and keeps the reports of the frames chosen for the report's strip.
class RunObserver : public Observer {
 public:
  RunObserver(ProgressBar& p, std::vector<KeptFrame>& strip) : progress_(p), strip_(strip) {}
  // Called from the feeding thread, before the frame is fed.
  void keep(std::size_t slot, const RgbdFrame& f) {
    std::lock_guard lock(mutex_);
    strip_[slot].frame = f;
  }
  // Called from the tracking thread.
  void on_frame(const FrameReport& r) override {
    reported_.fetch_add(1);
    advance(tracking::to_string(r.state));
    std::lock_guard lock(mutex_);
    const std::array<std::size_t, 4> removal = {r.removal.dynamic_total, r.removal.dynamic_removed,
                                                r.removal.static_total, r.removal.static_kept};
    rows_.push_back({r.t, r.state, r.features, r.dynamic_features, r.inliers, r.detections,
                     r.keyframe, r.latency_ms, r.source, r.imu_chi2, removal, r.local_points,
                     r.visible_points});
    for (KeptFrame& k : strip_) {
      if (!k.frame.color.empty() && k.frame.t == r.t) k.report = r;
    }
  }
  // Called from the mapping thread, and last from finish(): the database after the run.
  void on_objects(const ObjectsReport& r) override {
    std::lock_guard lock(mutex_);
    objects_ = r.objects;
  }
  std::vector<semantic::SemanticObject> objects() {
    std::lock_guard lock(mutex_);
    return objects_;
  }
  // Seconds from the first reported frame to the first one relocalized (the one tracking
  // thread reports frames in stamp order); nullopt: none was.
  std::optional<double> first_relocalized_after_s() {
    std::lock_guard lock(mutex_);
    for (const Row& row : rows_) {
      if (row.state == tracking::TrackingState::kRelocalized) {
        return to_seconds(row.t - rows_.front().t);
      }
    }
    return std::nullopt;
  }
  // Called from the feeding thread for a frame that is not fed (a live run's drop).
  void skip() { advance("dropping"); }
  std::size_t reported() const { return reported_.load(); }
  std::vector<std::pair<double, double>> latencies() {
    std::lock_guard lock(mutex_);
    std::vector<std::pair<double, double>> out;
    out.reserve(rows_.size());
    for (const auto& row : rows_) out.emplace_back(to_seconds(row.t), row.latency_ms);
    return out;
  }
  // One line per frame, so a user can see where and why a track was lost (frames.csv).
  void write_frames_csv(const std::string& path) {
    std::lock_guard lock(mutex_);
    std::ofstream out(path);
    // With ground-truth mover masks, four columns say how the filter did on this frame (features
    // truly on movers and how many it removed, truly static and how many it kept). The last two
    // are the local map's size and its points in view: few in view while static features abound
    // means the map lacked points where the camera looked; many in view with few inliers, that
    // they did not match.
    out << "#t [s],state,features,dynamic,inliers,detections,keyframe,latency [ms],pose,imu chi2,"
           "true dynamic,removed,true static,kept,local points,visible points\n";
    char line[256];
    for (const Row& r : rows_) {
      std::snprintf(line, sizeof(line),
                    "%.9f,%s,%d,%d,%d,%d,%d,%.2f,%s,%.3g,%zu,%zu,%zu,%zu,%d,%d\n", to_seconds(r.t),
                    tracking::to_string(r.state), r.features, r.dynamic, r.inliers, r.detections,
                    r.keyframe ? 1 : 0, r.latency_ms, to_string(r.source), r.imu_chi2, r.removal[0],
                    r.removal[1], r.removal[2], r.removal[3], r.local_points, r.visible_points);
      out << line;
    }
    if (!out) throw Error::at(path, 0, "", "write error");
  }

 private:
  struct Row {
    Timestamp t;
    tracking::TrackingState state;
    int features, dynamic, inliers, detections;
    bool keyframe;
    double latency_ms;
    PoseSource source;
    double imu_chi2;
    // dynamic total, removed, static total, kept: a row per frame for the whole run, so not
    // the whole RemovalCounts with its per-reason tables.
    std::array<std::size_t, 4> removal;
    int local_points, visible_points;
  };
  // The tracking thread reports frames, the feeding thread the ones it drops.
  void advance(const char* state) {
    std::lock_guard lock(progress_mutex_);
    progress_.update(++done_, state);
  }
  ProgressBar& progress_;
  std::vector<KeptFrame>& strip_;
  std::mutex mutex_;
  std::mutex progress_mutex_;
  std::size_t done_ = 0;
  std::atomic<std::size_t> reported_{0};
  std::vector<Row> rows_;
  std::vector<semantic::SemanticObject> objects_;
};

// Indices of n frames spread evenly over total, away from the very first frames.
std::vector<std::size_t> strip_indices(std::size_t total, std::size_t n) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < n && total > 0; ++i) out.push_back((2 * i + 1) * total / (2 * n));
  return out;
}

}  // namespace

double peak_rss_mib(const std::vector<MemorySample>& samples) {
  double peak = 0.0;
  for (const MemorySample& m : samples) peak = std::max(peak, m.rss_mib);
  return peak;
}

bool mode_uses_imu(const std::string& mode, const Calibration& calib) {
  if (mode == "auto") return calib.has_imu;
  const bool stereo = mode.rfind("stereo", 0) == 0;
  const bool with_imu = mode.ends_with("-imu");
  if (mode != "rgbd" && mode != "rgbd-imu" && mode != "stereo" && mode != "stereo-imu") {
    throw Error("--mode: unknown mode '" + mode + "' (auto, rgbd, rgbd-imu, stereo or stereo-imu)");
  }
  if (stereo != calib.is_stereo()) {
    throw Error("--mode " + mode + ": the dataset is " +
                (calib.is_stereo() ? "stereo" : "RGB-D / monocular") + ", not " +
                (stereo ? "stereo" : "RGB-D"));
  }
  if (with_imu && !calib.has_imu) {
    throw Error("--mode " + mode + ": the dataset's calibration has no IMU");
  }
  return with_imu;
}

RunSummary run_sequence(io::MeasurementSource& source, const RunOptions& options) {
  std::unique_ptr<detect::Detector> detector;
  if (options.detector == "yolo") {
    const std::string dir =
        options.models_dir.empty() ? detect::find_models_dir() : options.models_dir;
    detector = std::make_unique<detect::YoloFastest>(
        dir, detect::pipeline_yolo_options(options.yolo_model));
  } else if (options.detector == "oracle") {
    if (options.dataset_dir.empty()) {
      throw Error("--detector oracle needs a Kestrel sequence with boxes.csv");
    }
    detector = std::make_unique<detect::OracleDetector>(
        io::read_boxes(options.dataset_dir + "/boxes.csv"), options.oracle);
  } else if (options.detector != "none") {
    throw Error("unknown detector '" + options.detector + "' (yolo, oracle or none)");
  }

  SystemOptions sys_opt;
  sys_opt.sequential = options.sequential;
  sys_opt.dynamic.mode = options.dynamic;
  sys_opt.use_imu = mode_uses_imu(options.mode, source.calibration());
  if (!options.loop_closing) sys_opt.vocabulary.clear();
  sys_opt.tracker.triangulate = options.triangulate;
  if (options.half_resolution_flow) dynamic::use_half_resolution_flow(sys_opt.dynamic);
  if (options.flow_skip_gate_px >= 0.0) sys_opt.dynamic.fb_skip_gate_px = options.flow_skip_gate_px;
  sys_opt.inertial_ba = options.inertial_ba;
  if (options.dense_map_interval_s >= 0.0)
    sys_opt.dense_map_interval_s = options.dense_map_interval_s;
  sys_opt.gyro_rotation_prior = options.gyro_rotation_prior;
  sys_opt.depth_carry = options.depth_carry;
  sys_opt.corner_tracks = options.corner_tracks;
  sys_opt.park_vehicles = options.park_vehicles;
  sys_opt.box_coasting.max_frames = options.carried_box_frames;
  sys_opt.mover_budget_margin_px = options.mover_budget_margin_px;
  sys_opt.mover_silhouettes = options.mover_silhouette_grow_px >= 0;
  if (sys_opt.mover_silhouettes)
    sys_opt.mover_silhouette.grow_px = options.mover_silhouette_grow_px;
  sys_opt.load_map = options.load_map;
  // With ground truth, the run's world is the truth's (nearest pose within 20 ms of the first
  // frame), so maps and objects can be scored against it; APE aligns anyway.
  if (auto gt = source.ground_truth(); gt && !gt->empty()) {
    sys_opt.initial_T_w_body = [gt = std::move(*gt)](Timestamp t) -> std::optional<SE3> {
      const auto i = nearest_pose(gt, to_seconds(t), 0.02);
      if (!i) return std::nullopt;
      return gt.poses[*i];
    };
  }
  System system(source.calibration(), sys_opt, std::move(detector));
  RunSummary summary;
  if (options.truth_masks) {
    summary.has_truth_masks = true;
    system.set_truth_masks(options.truth_masks);
  } else if (!options.dataset_dir.empty() &&
             std::filesystem::exists(options.dataset_dir + "/dynamic")) {
    summary.has_truth_masks = true;
    const std::string dir = options.dataset_dir;
    system.set_truth_masks([dir](Timestamp t) { return io::read_dynamic_mask(dir, t); });
  }
  if (options.progress && !options.progress_label.empty()) {
    std::printf("%s\n", options.progress_label.c_str());
  }
  ProgressBar progress(source.frame_count(), "frames", options.progress);
  const std::vector<std::size_t> keep = strip_indices(source.frame_count(), options.strip_frames);
  summary.strip.resize(keep.size());
  RunObserver observer(progress, summary.strip);
  system.add_observer(&observer);

  const auto t0 = std::chrono::steady_clock::now();
  std::size_t next_keep = 0;
  std::optional<Timestamp> first_stamp;
  double next_memory_s = 0.0;
  std::int64_t stream_ns = 0;
  std::size_t fed_frames = 0;
  const bool live = options.paced && !options.sequential;  // frames may be dropped
  while (auto m = source.next()) {
    const Timestamp stamp = stamp_of(*m);
    if (!first_stamp) first_stamp = stamp;
    const std::int64_t since_first = stamp - *first_stamp;
    stream_ns = std::max(stream_ns, since_first);
    if (options.paced) {
      const double rate = options.pace_rate > 0.0 ? options.pace_rate : 1.0;
      std::this_thread::sleep_until(
          t0 + std::chrono::nanoseconds(static_cast<std::int64_t>(since_first / rate)));
    }
    if (options.memory_sample_s > 0 && !std::holds_alternative<ImuSample>(*m) &&
        to_seconds(since_first) >= next_memory_s) {
      summary.memory.push_back({to_seconds(since_first), resident_mib()});
      next_memory_s += options.memory_sample_s;
    }
    // The IMU samples all go in: they are what bridges a dropped frame's gap.
    if (live && !std::holds_alternative<ImuSample>(*m) &&
        drop_live_frame(fed_frames, observer.reported(), options.max_frames_in_flight)) {
      ++summary.frames;
      ++summary.dropped;
      observer.skip();
      continue;
    }
    if (next_keep < keep.size() && summary.frames >= keep[next_keep]) {
      if (const auto* f = std::get_if<RgbdFrame>(&*m)) {
        observer.keep(next_keep++, *f);
      } else if (const auto* st = std::get_if<StereoFrame>(&*m)) {
        RgbdFrame left;  // the report shows the left image of a stereo pair
        left.t = st->t;
        left.color = st->left;
        left.source = st->source;
        observer.keep(next_keep++, left);
      }
    }
    system.feed(*m);
    if (!std::holds_alternative<ImuSample>(*m)) ++summary.frames, ++fed_frames;
  }
  system.finish();
  if (options.memory_sample_s > 0) {
    summary.memory.push_back({to_seconds(stream_ns), resident_mib()});
  }
  summary.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const Trajectory traj = system.trajectory();
  summary.lost = system.frames_lost();
  const auto counters = system.stats().counters();
  if (auto it = counters.find("frames.inertial_only"); it != counters.end()) {
    summary.inertial_only = it->second;
  }
  if (auto it = counters.find("frames.depth_imu"); it != counters.end()) {
    summary.depth_imu = it->second;
  }
  if (auto it = counters.find("frames.frame_to_frame"); it != counters.end()) {
    summary.frame_to_frame = it->second;
  }
  if (auto it = counters.find("tracking.bridged"); it != counters.end()) {
    summary.bridged = it->second;
  }
  summary.tracked = traj.size() - std::min(traj.size(), summary.inertial_only);
  if (!options.load_map.empty()) {
    summary.map_relocalized_after_s = observer.first_relocalized_after_s().value_or(-1.0);
  }
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
  summary.stages = stages;
  for (const auto& entry : stages) {
    summary.stage_timelines[entry.first] = system.stats().timed_samples(entry.first);
  }
  summary.counters = system.stats().counters();
  // The feeding side's drops sit beside the System's own queue counters.
  summary.counters["frames.dropped"] = summary.dropped;
  nlohmann::json timing = nlohmann::json::parse(system.stats().to_json());
  timing["counters"]["frames.dropped"] = summary.dropped;
  summary.timing_json = timing.dump(2);
  summary.trajectory = traj;
  summary.frame_latencies = observer.latencies();
  // Frames never read (a short source) leave empty slots.
  std::erase_if(summary.strip, [](const KeptFrame& k) { return k.frame.color.empty(); });

  if (auto gt = source.ground_truth(); gt && !gt->empty()) summary.ground_truth = std::move(gt);
  if (const auto& gt = summary.ground_truth; gt && traj.size() >= 3) {
    eval::ApeOptions ape;
    ape.association.method = eval::AssociationMethod::kEvo;
    ape.association.max_diff = 0.01;
    ape.alignment = eval::Alignment::kSe3;
    const eval::Evaluation e =
        eval::evaluate_ape(io::to_pose_series(*gt), io::to_pose_series(traj), ape);
    summary.ape_rmse_m = e.stats.rmse;
    summary.ape_pairs = e.stats.count;
  }

  // A simulated sequence knows its world: the run's objects are scored against it.
  // A world that cannot be read costs the score, not the run's outputs.
  if (summary.ground_truth && !options.dataset_dir.empty()) {
    try {
      if (const auto truth = read_object_truth(options.dataset_dir, *summary.ground_truth,
                                               source.calibration().T_body_camera)) {
        std::vector<eval::ObjectBox> reported;
        for (const semantic::SemanticObject& o : observer.objects()) {
          reported.push_back({o.label, o.box.center, o.box.size, o.box.yaw, o.observations});
        }
        summary.objects = score_run_objects(*truth, reported);
      }
    } catch (const std::exception& e) {
      summary.objects_error = e.what();
    }
  }

  if (!options.out_dir.empty()) {
    const auto t_write = std::chrono::steady_clock::now();
    std::filesystem::create_directories(options.out_dir);
    io::write_tum(options.out_dir + "/trajectory.txt", traj);
    observer.write_frames_csv(options.out_dir + "/frames.csv");
    system.write_map_outputs(options.out_dir);
    std::ofstream(options.out_dir + "/timing.json") << summary.timing_json << "\n";
    // summary.json is the last file and carries the time of all the others but itself.
    summary.outputs_write_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_write).count();
    for (const auto& e : std::filesystem::directory_iterator(options.out_dir)) {
      if (!e.is_regular_file()) continue;
      ++summary.outputs_files;
      summary.outputs_bytes += e.file_size();
    }
    std::ofstream(options.out_dir + "/summary.json") << summary_json(summary) << "\n";
  }
  return summary;
}

std::string summary_json(const RunSummary& s) {
  nlohmann::json j;
  j["frames"] = s.frames;
  j["dropped"] = s.dropped;
  j["tracked"] = s.tracked;
  j["lost"] = s.lost;
  j["inertial_only"] = s.inertial_only;
  j["depth_imu"] = s.depth_imu;
  j["frame_to_frame"] = s.frame_to_frame;
  j["bridged"] = s.bridged;
  if (s.map_relocalized_after_s) j["map_relocalized_after_s"] = *s.map_relocalized_after_s;
  j["ape_rmse_m"] = s.ape_rmse_m;
  j["ape_pairs"] = s.ape_pairs;
  if (s.has_truth_masks) {
    j["dynamic_removed_percent"] = s.removal.removed_percent();
    j["static_kept_percent"] = s.removal.kept_percent();
    j["dynamic_features"] = s.removal.dynamic_total;
    j["static_features"] = s.removal.static_total;
  }
  if (!s.objects_error.empty()) j["objects_error"] = s.objects_error;
  if (s.objects) {
    const eval::ObjectScores& o = *s.objects;
    j["objects"] = {{"truth", o.truth},
                    {"reported", o.reported},
                    {"matched", o.matched},
                    {"recall", o.recall},
                    {"precision", o.precision},
                    {"class_correct", o.class_correct},
                    {"center_error_median_m", o.center_error_median},
                    {"size_error_median", o.size_error_median}};
  }
  j["tracking_ms_median"] = s.tracking_ms_median;
  j["tracking_fps"] = s.tracking_ms_median > 0 ? 1000.0 / s.tracking_ms_median : 0.0;
  j["detector_ms_median"] = s.detector_ms_median;
  j["detector_fps"] = s.detector_ms_median > 0 ? 1000.0 / s.detector_ms_median : 0.0;
  j["wall_seconds"] = s.wall_seconds;
  if (s.outputs_write_s >= 0) {
    j["outputs_write_s"] = s.outputs_write_s;
    j["outputs_files"] = s.outputs_files;
    j["outputs_bytes"] = s.outputs_bytes;
  }
  if (!s.memory.empty()) {
    j["rss_mib_end"] = s.memory.back().rss_mib;
    j["rss_mib_peak"] = peak_rss_mib(s.memory);
    nlohmann::json samples = nlohmann::json::array();
    for (const MemorySample& m : s.memory) samples.push_back({m.stream_s, m.rss_mib});
    j["rss_mib_samples"] = samples;  // [stream seconds, MiB]
  }
  return j.dump(2);
}

}  // namespace kestrel::pipeline
