#pragma once
// The dynamic filter alone over a recorded Kestrel sequence, scored against its ground-truth
// mover masks: the same inputs the System gives it frame by frame (the tracker's features with
// the sensor's depth under them, the gyro rotation since the previous frame, the IMU's predicted
// translation, a detector's dynamic-class boxes), without tracking or mapping. Shared by `kestrel
// bench dynamic` and the tests; each detector runs once per scene and every filter mode reuses its
// boxes.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.hpp"
#include "core/eigen_types.hpp"
#include "core/image.hpp"
#include "core/timestamp.hpp"
#include "detect/box_coasting.hpp"
#include "detect/detection.hpp"
#include "detect/detector.hpp"
#include "detect/dynamic_classes.hpp"
#include "dynamic/dynamic_filter.hpp"
#include "dynamic/mover_silhouette.hpp"
#include "dynamic/parked_boxes.hpp"
#include "dynamic/removal_metrics.hpp"
#include "pipeline/mover_mask.hpp"

namespace kestrel::pipeline {

struct DynamicEvalFrame {
  Timestamp t = 0;
  Image gray;
  Image mask;   // 16-bit mover ids (0 = static)
  Image depth;  // 16-bit, metres = value / depth_scale
  double depth_scale = 5000.0;
  std::vector<Vec2> points;
  std::vector<double> depth_m;     // sensor depth under each feature (0: none)
  std::optional<Mat3> R_cur_prev;  // gyro rotation from the previous frame
  // The camera's translation since the previous frame as the IMU predicts it, with the sigmas
  // the System gives the filter (dynamic::DynamicFilterInput::t_cur_prev): the System's own
  // imu::InertialPredictor, fed the recorded IMU and, where the System has its tracked poses, the
  // ground-truth poses of the frames before. Nothing without ground truth or IMU, or before the
  // predictor has its velocity window.
  std::optional<Vec3> t_cur_prev;
  double prior_translation_sigma_m = 0.0;
  double prior_rotation_sigma_rad = 0.0;
  std::vector<detect::DetectionSet> detections;  // one per detector given to the loader
};

struct DynamicEvalScene {
  std::string dir;
  Mat3 K = Mat3::Identity();
  PinholeCamera camera;        // the features are extracted again with it (mover_budget)
  double depth_range_m = 0.0;  // Calibration::depth_max (0: not given)
  std::vector<DynamicEvalFrame> frames;
};

// Reads the sequence at `dir` (a Kestrel sequence with dynamic/ masks), extracts features as
// the System's tracker does and runs every detector on every frame. max_frames 0: all. Throws
// kestrel::Error naming the file for a missing or malformed sequence.
DynamicEvalScene load_dynamic_eval_scene(const std::string& dir,
                                         const std::vector<detect::Detector*>& detectors,
                                         std::size_t max_frames = 0);

struct DynamicEvalOptions {
  dynamic::DynamicFilterOptions filter;
  int detector = -1;                         // index into the frames' detections; -1: no boxes
  std::vector<std::string> dynamic_classes;  // empty: detect::default_dynamic_classes()
  float mover_min_score = detect::kMoverMinScore;  // as SystemOptions::mover_min_score
  // Parked vehicles judged as scenery, as the System does (SystemOptions::park_vehicles).
  bool park_vehicles = true;
  std::vector<std::string> parkable_classes;  // empty: detect::default_parkable_classes()
  dynamic::ParkedBoxOptions parked;
  // A mover's box carried across the frames its detection misses, as the System does
  // (SystemOptions::box_coasting).
  detect::BoxCoastOptions box_coasting;
  // As SystemOptions::mover_budget_margin_px: a frame after one with mover boxes has its
  // features extracted again with those boxes set apart (negative: off).
  int mover_budget_margin_px = -1;
  // ... and, as SystemOptions::mover_silhouettes, no features where the previous frame's movers
  // were. With either, such a frame's features are extracted again; with neither, they are the
  // loader's.
  bool mover_silhouettes = true;
  dynamic::MoverSilhouetteOptions mover_silhouette;
  bool prev_depth = true;  // give the filter the previous frame's depth image
  // Give the filter the IMU's predicted translation (DynamicEvalFrame::t_cur_prev), as the System
  // does (SystemOptions::dynamic_motion_prior); only against the previous frame (gap 1).
  bool motion_prior = true;
  int gap = 1;  // judge frame k against frame k - gap (the first ones against 0)
  // Multi-frame evidence: also judge frame k against frame k - long_gap and combine the two
  // (dynamic::combine_baselines); 0: off.
  int long_gap = 0;
  dynamic::MultiFrameOptions multi_frame;
  // Called for every judged frame (after the first), e.g. to score a subset of the movers.
  std::function<void(const DynamicEvalFrame&, const dynamic::DynamicFilterInput&,
                     const dynamic::DynamicFilterResult&)>
      on_frame;
};

struct DynamicEvalResult {
  dynamic::RemovalCounts counts;
  std::vector<double> filter_ms;      // per frame, wall clock
  std::vector<double> filter_cpu_ms;  // per frame, the thread's CPU time (core/thread_cpu_time)
};

// Runs the filter frame after frame, each frame against the previous one (or the one `gap`
// frames back) as the System does, and counts removal against the masks.
DynamicEvalResult evaluate_dynamic_filter(const DynamicEvalScene& scene,
                                          const DynamicEvalOptions& options);

}  // namespace kestrel::pipeline
