#pragma once
// One run of the system over a dataset, as `kestrel run`, `kestrel demo` and `kestrel bench`
// do it: feed the stream, write the outputs, score against ground truth where there is one.
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/frame.hpp"
#include "core/trajectory.hpp"
#include "detect/box_coasting.hpp"
#include "detect/oracle_detector.hpp"
#include "detect/yolo_fastest.hpp"
#include "dynamic/dynamic_filter.hpp"
#include "dynamic/removal_metrics.hpp"
#include "eval/object_metrics.hpp"
#include "io/measurement_source.hpp"
#include "pipeline/stage_stats.hpp"
#include "pipeline/system.hpp"

namespace kestrel::pipeline {

struct RunOptions {
  std::string dataset_dir;        // for the Kestrel sequence's truth files (boxes, masks)
  std::string detector = "yolo";  // yolo | oracle | none
  detect::YoloModel yolo_model = detect::kPipelineYoloModel;
  detect::OracleOptions oracle;  // noise of the oracle detector (false negatives, jitter)
  dynamic::FilterMode dynamic = dynamic::FilterMode::kHybrid;
  bool sequential = true;
  // auto | rgbd | rgbd-imu | stereo | stereo-imu; auto takes the richest the dataset offers.
  // A mode the dataset cannot give (stereo of an RGB-D sequence, IMU without one) is an error.
  std::string mode = "auto";
  bool loop_closing = true;
  bool triangulate = true;             // TrackerOptions::triangulate
  bool half_resolution_flow = false;   // dynamic::use_half_resolution_flow
  double flow_skip_gate_px = -1.0;     // DynamicFilterOptions::fb_skip_gate_px (<0: unchanged)
  bool inertial_ba = false;            // SystemOptions::inertial_ba
  double dense_map_interval_s = -1.0;  // SystemOptions::dense_map_interval_s (<0: unchanged)
  bool gyro_rotation_prior = true;     // SystemOptions::gyro_rotation_prior
  bool depth_carry = true;             // SystemOptions::depth_carry
  bool corner_tracks = true;           // SystemOptions::corner_tracks
  bool park_vehicles = true;           // SystemOptions::park_vehicles
  std::string out_dir;                 // trajectory.txt, timing.json, summary.json
  std::string models_dir;              // "" = find ../shared/models
  std::string load_map;                // SystemOptions::load_map: map.bin of an earlier session
  // SystemOptions::box_coasting.max_frames
  int carried_box_frames = detect::BoxCoastOptions{}.max_frames;
  // SystemOptions::mover_budget_margin_px (negative: one feature budget for the whole image)
  int mover_budget_margin_px = SystemOptions{}.mover_budget_margin_px;
  // SystemOptions::mover_silhouette.grow_px (negative: SystemOptions::mover_silhouettes off)
  int mover_silhouette_grow_px = SystemOptions{}.mover_silhouette.grow_px;
  bool progress = true;
  std::string progress_label;    // printed before the bar when not empty
  std::size_t strip_frames = 4;  // frames kept (evenly spread) for the report's strip
  // Feed each measurement no earlier than its stamp says, counted from the first one, as a live
  // sensor delivers it; with sequential = false this is a real-time run, and frame_latency is
  // what a live user waits from frame arrival to pose.
  bool paced = false;
  double pace_rate = 1.0;  // paced: this many times the sensor's rate (tests: a source too fast)
  // Paced and not sequential (a live run): a live camera does not wait for the tracker, so a
  // frame that arrives while this many are still in flight is dropped (counted, no pose),
  // as kestrel agent does. 0: every frame is fed and the source waits (the frame queue's
  // back-pressure), which lets latency grow without bound once the system falls behind.
  int max_frames_in_flight = 2;
  // Mover masks for the removal figures when the source is not a sequence on disk (the live
  // simulator); else they are read from dataset_dir/dynamic when it exists.
  TruthMaskProvider truth_masks;
  // Resident memory is sampled every this many seconds of stream time (0: never).
  double memory_sample_s = 0.0;
};

// Resident memory of this process at a moment of the run.
struct MemorySample {
  double stream_s = 0.0;  // seconds since the first measurement's stamp
  double rss_mib = 0.0;
};

// A frame kept for the report, with what the system said about it.
struct KeptFrame {
  RgbdFrame frame;
  FrameReport report;
};

struct RunSummary {
  std::size_t frames = 0;
  std::size_t dropped = 0;  // live: frames not fed because the tracker was busy (no pose)
  std::size_t tracked = 0;  // frames with a visual pose
  std::size_t lost = 0;
  std::size_t inertial_only = 0;   // lost frames whose pose the IMU carried (in the trajectory)
  std::size_t depth_imu = 0;       // lost frames aligned by depth with the IMU's prior (trajectory)
  std::size_t frame_to_frame = 0;  // lost to the map, its step from the frame before fixed by depth
  // tracked frames that restarted the local map (PoseSource::kBridged) at the IMU's pose, or
  // at the last one without a prediction (tracking.restarted): their pose is not vision's; the
  // frames after them are tracked against the map they seeded
  std::size_t bridged = 0;
  // With RunOptions::load_map: seconds from the first frame to the first one relocalized in the
  // loaded map (-1: none was); unset without a map to load.
  std::optional<double> map_relocalized_after_s;
  double ape_rmse_m = -1.0;  // -1 without ground truth
  std::size_t ape_pairs = 0;
  dynamic::RemovalCounts removal;
  bool has_truth_masks = false;
  // The run's objects against the world's (a simulated sequence: pipeline/sequence_object_truth).
  std::optional<eval::ObjectScores> objects;
  std::string objects_error;        // why they could not be scored (the world's files), if so
  double tracking_ms_median = 0.0;  // per frame: features + dynamic filter + tracking
  double detector_ms_median = 0.0;
  double wall_seconds = 0.0;
  // With RunOptions::out_dir: seconds to write the run's files there (trajectory, frames.csv,
  // map.bin, sparse and dense clouds, OctoMap, 2D grid, objects, timing, summary), how many
  // files the folder then holds and their bytes; -1 without out_dir.
  double outputs_write_s = -1.0;
  std::size_t outputs_files = 0;
  std::uintmax_t outputs_bytes = 0;
  std::string timing_json;
  // For the report and the benchmark: the estimate, the reference, every stage's latency.
  Trajectory trajectory;
  std::optional<Trajectory> ground_truth;
  std::map<std::string, LatencySummary> stages;
  std::map<std::string, std::size_t> counters;
  std::vector<KeptFrame> strip;
  std::vector<MemorySample> memory;  // with memory_sample_s > 0; the last is after finish()
  // Every reported frame's stamp (s) and its frame-to-pose latency (ms), in report order: how
  // latency moves along a long run, which the whole run's percentiles hide.
  std::vector<std::pair<double, double>> frame_latencies;
  // Every stage's samples as (s since the System started, ms): with a live run's pace, where
  // along the run a stage grows.
  std::map<std::string, std::vector<std::pair<double, double>>> stage_timelines;
};

// The largest resident memory among the samples (0 for none).
double peak_rss_mib(const std::vector<MemorySample>& samples);

// Whether the run uses the IMU, for a mode and what the calibration offers; throws
// kestrel::Error naming the mode when the dataset cannot give it.
bool mode_uses_imu(const std::string& mode, const Calibration& calib);

// Throws kestrel::Error for unknown detectors or unreadable inputs.
RunSummary run_sequence(io::MeasurementSource& source, const RunOptions& options);

// summary.json text (the figures `kestrel demo` prints, for tests and the report).
std::string summary_json(const RunSummary& s);

}  // namespace kestrel::pipeline
