#include "pipeline/system.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <unordered_map>

#include "detect/dynamic_classes.hpp"
#include "imu/imu_initializer.hpp"
#include "imu/inertial_local_ba.hpp"
#include "imu/preintegration.hpp"
#include "io/cv_image.hpp"
#include "loop/edge_sigmas.hpp"
#include "loop/loop_detector.hpp"
#include "loop/place_view.hpp"
#include "loop/pose_graph.hpp"
#include "loop/vocabulary.hpp"
#include "mapping/map_io.hpp"
#include "maps/map_builder.hpp"
#include "pipeline/bounded_queue.hpp"
#include "pipeline/detection_buffer.hpp"
#include "pipeline/imu_buffer.hpp"
#include "pipeline/thread_priority.hpp"
#include "semantic/object_database.hpp"
#include "tracking/stereo_matcher.hpp"

namespace kestrel::pipeline {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kRejectedPatch = 8;  // pixels masked around a feature rejected as dynamic
constexpr Timestamp kSecond = 1'000'000'000;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// What the mapping thread needs of a keyframe (the images are shared, not copied).
struct MappingJob {
  std::int64_t keyframe_id = 0;
  Timestamp t = 0;
  SE3 T_w_c;
  RgbdFrame frame;
  std::vector<maps::MapBoxRegion> masked;       // dynamic boxes and rejected features
  std::vector<detect::Detection> static_boxes;  // chair, tv, ... for the object database
  std::vector<detect::Detection> moving_boxes;
};

// What the loop-closing thread needs of a keyframe (a copy: the tracker keeps its map).
struct LoopJob {
  loop::PlaceView view;
  Timestamp t = 0;
  SE3 T_w_c;
  // The keyframe restarted the local map after a lost track (bridged at the IMU's pose, or
  // restarted at the last one): the odometry jumps here, by however far the body went unseen.
  bool after_restart = false;
  // ... and the IMU held the attitude across it (a bridge at its prediction, a restart at the
  // gyro's attitude): only the position is unknown there, so a loop across it still answers to
  // the odometry's rotation.
  bool attitude_held = false;
  // The tracker culled keyframe view.id: drop its place (its pose-graph node stays, so loop
  // corrections still move what was anchored to it).
  bool forget = false;
};

struct QueuedFrame {
  RgbdFrame frame;  // a stereo pair's left image as a monocular frame, without depth
  Clock::time_point arrival;
  Image right;  // stereo only: depth comes from matching against it
};

Image to_gray(const Image& color) {
  if (color.channels == 1) return color;
  cv::Mat gray;
  cv::cvtColor(io::as_mat(color), gray, cv::COLOR_BGR2GRAY);
  return io::to_image(gray);
}

}  // namespace

const char* to_string(PoseSource s) {
  switch (s) {
    case PoseSource::kNone:
      return "none";
    case PoseSource::kVision:
      return "vision";
    case PoseSource::kVisionImu:
      return "vision-imu";
    case PoseSource::kBridged:
      return "bridged";
    case PoseSource::kImu:
      return "imu";
    case PoseSource::kDepthImu:
      return "depth-imu";
    case PoseSource::kFrameToFrame:
      return "frame-to-frame";
  }
  return "?";
}

InertialPriorSigmas inertial_prior_sigmas(const SystemOptions& options, double since_fix_s) {
  const double h = since_fix_s;
  return {options.inertial_prior_rotation_sigma * (1.0 + h / 0.1),
          options.inertial_prior_translation_sigma + 0.05 * h + 0.5 * h * h};
}

double inertial_prior_age(double since_fix_s, double since_bridge_s) {
  return since_bridge_s >= 0.0 ? std::min(since_fix_s, since_bridge_s) : since_fix_s;
}

struct System::Impl {
  Calibration calib;
  SystemOptions options;
  std::unique_ptr<detect::Detector> detector;
  detect::DynamicClassList dynamic_classes;
  detect::DynamicClassList parkable_classes;
  dynamic::ParkedBoxTracker parked_boxes;  // tracking thread
  detect::BoxCoaster box_coaster;          // tracking thread
  // The last frame's mover boxes (parked ones marked): where this frame's movers are expected
  // when its features are extracted, before its own boxes arrive. Tracking thread.
  std::vector<dynamic::BoxRegion> last_boxes;
  tracking::Tracker tracker;
  std::unique_ptr<tracking::StereoMatcher> stereo;  // stereo calibrations only

  BoundedQueue<QueuedFrame> frames;
  BoundedQueue<RgbdFrame> detection_frames;
  DetectionBuffer detections;
  std::mutex imu_mutex;
  std::condition_variable imu_cv;  // IMU sample, frame or end of input arrived
  ImuBuffer imu;
  Timestamp newest_frame_fed = 0;  // under imu_mutex
  bool input_closed = false;       // under imu_mutex
  StageStats stats;
  TruthMaskProvider truth;

  std::vector<Observer*> observers;
  mutable std::mutex result_mutex;
  Trajectory trajectory;
  dynamic::RemovalCounts removal;
  std::size_t lost = 0;

  std::thread tracking_thread;
  std::thread detection_thread;
  std::thread mapping_thread;
  // Mapping thread: objects per keyframe, and the dense maps for one keyframe every
  // options.dense_map_interval_s. Never drops a keyframe: the tracking thread waits when it
  // falls behind (DESIGN.md).
  BoundedQueue<MappingJob> mapping_jobs{8, FullPolicy::kBlock};
  std::optional<Timestamp> last_dense_t;  // the latest keyframe the dense maps took
  maps::MapBuilder map_builder{maps::map_builder_options(calib.depth_max)};
  semantic::ObjectDatabase objects;
  // Loop-closing thread: place recognition on every keyframe; the pose graph over keyframes
  // runs when the run ends and corrects keyframes, objects and the trajectory.
  std::thread loop_thread;
  // Local-mapping thread: the local BA of each new keyframe, solved on a copy of its window
  // (mapping::gather_local_ba) and written back by the tracking thread before its next frame.
  // The newest keyframe's request supersedes one not yet started; sequential runs wait for
  // each solve, so they stay reproducible.
  std::thread ba_thread;
  std::mutex ba_mutex;
  std::condition_variable ba_cv;
  std::optional<mapping::LocalBaProblem> ba_request;  // under ba_mutex
  std::vector<mapping::LocalBaSolution> ba_results;   // under ba_mutex
  // The same thread searches each new keyframe for points from two views first (its local BA
  // needs them); the keyframe's insertion completes when the tracking thread writes them back.
  struct TriangulationResult {
    mapping::KeyframeId keyframe = -1;
    std::vector<mapping::NewMapPoint> points;
  };
  std::optional<mapping::TriangulationProblem> tri_request;  // under ba_mutex
  std::vector<TriangulationResult> tri_results;              // under ba_mutex
  bool ba_busy = false;                                      // under ba_mutex
  bool ba_stop = false;                                      // under ba_mutex
  std::size_t ba_superseded = 0;                             // under ba_mutex
  std::size_t ba_outliers = 0;                               // tracking thread
  std::vector<mapping::KeyframeId> awaiting_ba;              // tracking thread: keyframes whose
                                                             // loop job waits for their local BA
  BoundedQueue<LoopJob> loop_jobs{16, FullPolicy::kBlock};
  std::unique_ptr<loop::Vocabulary> vocabulary;
  std::unique_ptr<loop::LoopDetector> loop_detector;
  std::map<loop::PoseId, SE3> keyframe_poses;  // T_w_c as tracked
  std::map<loop::PoseId, Timestamp> keyframe_stamps;
  std::vector<loop::PoseGraphEdge> graph_edges;
  std::size_t loops = 0;
  std::size_t loops_rejected = 0;
  std::set<loop::PoseId> restarts;        // loop thread: keyframes that restarted the local map
  std::set<loop::PoseId> blind_restarts;  // ... of them, those where nothing held the attitude
  std::atomic<bool> finished{false};

  // Tracking-thread state.
  bool world_initialized = false;
  // Keyframes that restarted the local map, until their place goes to the loop thread, and
  // whether the IMU held the attitude across the restart.
  std::unordered_map<mapping::KeyframeId, bool> restart_keyframes;
  Image prev_gray;
  dynamic::FlowPyramid prev_pyramid;  // prev_gray's, kept from the filter's last call
  dynamic::ResidualTrail prev_trail;  // the filter's last call's (DynamicFilterOptions::trail)
  Image prev_depth;  // for the filter's depth-change test (a mover walking at the camera)
  double prev_depth_scale = 5000.0;
  Timestamp prev_t = 0;
  // Gyro rotation of the body since keyframe kf_gyro_from (-1: none), integrated up to gyro_t.
  mapping::KeyframeId kf_gyro_from = -1;
  SO3 kf_gyro_R;
  double kf_gyro_dt = 0.0;
  std::optional<imu::Preintegration> kf_pre;  // the same interval, fully pre-integrated
  Timestamp gyro_t = 0;
  std::optional<SE3> prev_T_w_c;      // the previous frame's camera pose: tracked, or the IMU's
  bool prev_tracked = false;          // ... and it was tracked by vision
  bool prev_frame_to_frame = false;   // ... or frame to frame (PoseSource::kFrameToFrame)
  std::optional<Vec3> predicted_v_w;  // the body velocity of this frame's IMU prediction
  bool inertial = false;              // IMU used at all (wait, gyro for the filter, prediction)
  bool imu_missing = false;      // under imu_mutex: the calibration has an IMU, the stream none
  Timestamp first_frame_t = -1;  // under imu_mutex
  // World gravity for the predictor: known when the world was aligned to gravity (ground truth
  // or the accelerometer before the first frame); else estimated from the first tracked
  // frames, and no prediction until then.
  bool gravity_known = false;
  Vec3 gravity_sum = Vec3::Zero();
  int gravity_samples = 0;
  imu::InertialPredictor predictor;
  Timestamp imu_fed_until = 0;   // predictor has the IMU up to here
  Timestamp last_bridge_t = -1;  // the latest bridge (TrackResult::bridged, not a restart)
  std::size_t inertial_frames = 0;
  std::size_t depth_frames = 0;  // lost to features, carried by depth and the IMU
  // Lost to the map, their step from the frame before fixed by depth and corners: not lost.
  std::size_t frame_to_frame_frames = 0;
  std::size_t depth_carry_refused = 0;  // alignments that moved the IMU's motion too far
  Timestamp last_vision_t = 0;          // stamp of the last frame features tracked
  // Vision's disagreement with the IMU (prior_chi2) over the last frames features tracked.
  static constexpr std::size_t recent_imu_chi2_frames = 10;
  std::deque<double> recent_imu_chi2;
  std::size_t bridged = 0;                   // lost tracks restarted at the IMU's pose
  std::size_t restarted = 0;                 // ... at the last pose, without a prediction
  std::size_t keyframes_culled = 0;          // tracking thread: redundant keyframes erased
  std::size_t prior_conflicts = 0;           // frames whose vision disagreed with the IMU
  std::size_t relocalizations_rejected = 0;  // too far from the IMU's pose
  std::size_t relocalizations_deferred = 0;  // lost while frames queued: no whole-map search

  Impl(const Calibration& c, SystemOptions o, std::unique_ptr<detect::Detector> d)
      : calib(c),
        options(std::move(o)),
        detector(std::move(d)),
        dynamic_classes(options.dynamic_classes.empty()
                            ? detect::DynamicClassList()
                            : detect::DynamicClassList(options.dynamic_classes)),
        parkable_classes(options.parkable_classes.empty()
                             ? detect::DynamicClassList(detect::default_parkable_classes())
                             : detect::DynamicClassList(options.parkable_classes)),
        parked_boxes(options.parked),
        box_coaster(options.box_coasting),
        tracker(c.camera,
                [&] {
                  tracking::TrackerOptions t = options.tracker;
                  if (options.async_local_ba) t.inline_mapping = false;
                  t.ba.inertial = options.inertial_ba && options.gyro_links;
                  // Stereo depth is as good as its matching: a pixel of the rig's own disparity.
                  if (c.is_stereo()) t.ba.virtual_bf = c.camera.fx * c.stereo_rig().baseline();
                  if (!options.inertial_prior) {
                    t.prior_in_optimization = false;
                    t.prior_gate_chi2 = options.inertial_gate_chi2;
                  }
                  return t;
                }()),
        frames(options.frame_queue, FullPolicy::kBlock),
        detection_frames(options.detection_queue,
                         options.sequential ? FullPolicy::kBlock : FullPolicy::kDropOldest),
        detections(options.detection_tolerance_ns),
        inertial(calib.has_imu && options.use_imu),
        predictor([&] {
          imu::InertialPredictorOptions o = options.inertial;
          o.noise = calib.imu;
          return o;
        }()) {
    loop::validate(options.pose_graph_sigmas);  // here, not first in the loop-closing thread
    if (options.mover_silhouettes) dynamic::validate(options.mover_silhouette, options.dynamic);
    if (calib.is_stereo()) {
      stereo = std::make_unique<tracking::StereoMatcher>(calib.stereo_rig(),
                                                         tracker.extractor().options());
    }
    if (!options.load_map.empty()) tracker.set_map(mapping::load_map(options.load_map));
  }

  void detection_loop() {
    while (auto f = detection_frames.pop()) {
      const auto t0 = Clock::now();
      detect::DetectionSet set = detector->detect(f->color, f->t);
      stats.record("detection", ms_since(t0));
      detections.put(std::move(set));
    }
  }

  void tracking_loop() {
    if (options.sequential) {
      while (auto q = frames.pop()) process(*q);
      return;
    }
    // Live, what the local-mapping thread solved (a keyframe's triangulated points, a local
    // BA) is written back while no frame waits: completing a keyframe (culling, the next local
    // BA's gather) took 8 ms at the median and 36 at p99 over the 10-minute endurance run, and
    // done as the next frame arrived it sat on that frame's latency.
    for (;;) {
      if (auto q = frames.pop_or_wake()) {
        process(*q);
      } else if (frames.closed()) {
        return;
      } else {
        apply_mapping_results(false);
      }
    }
  }

  // Left features with depth from the right image (the RGB-D tracker then takes them as is).
  tracking::FrameFeatures process_stereo(const QueuedFrame& q) {
    tracking::FrameFeatures f = tracker.extractor().extract(q.frame);
    if (!stereo) return f;  // a pair without a stereo calibration: monocular
    const auto t0 = Clock::now();
    stereo->compute_depth(f, q.frame.color, q.right);
    stats.record("features.stereo", ms_since(t0));
    return f;
  }

  // Time synchronization: a frame waits until the IMU has passed its stamp, so that its
  // interval is integrated exactly. The source is time-ordered, so a newer frame or the end of
  // input means the IMU for this one will not come; live runs also give up after imu_wait_ms.
  // A calibration with an IMU whose stream brings none for a second stops the waiting (and the
  // prediction); imu.missing says so.
  void wait_for_imu(Timestamp t) {
    std::unique_lock<std::mutex> lock(imu_mutex);
    if (imu_missing) return;
    if (first_frame_t < 0) first_frame_t = t;
    if (imu.empty() && t - first_frame_t > kSecond) {
      imu_missing = true;
      return;
    }
    auto ready = [&] { return imu.latest() >= t || newest_frame_fed > t || input_closed; };
    // Sequential: the feeder's next measurement releases it; the bound only guards a caller
    // that waits for this frame's report before feeding on.
    const auto bound = options.sequential
                           ? std::chrono::duration<double, std::milli>(30'000.0)
                           : std::chrono::duration<double, std::milli>(options.imu_wait_ms);
    imu_cv.wait_for(lock, bound, ready);
  }

  // Hands the IMU up to frame t to the predictor and returns its guess of the camera pose.
  std::optional<tracking::MotionPrior> inertial_prediction(Timestamp t) {
    predicted_v_w.reset();
    if (!inertial) return std::nullopt;
    std::vector<ImuSample> s;
    {
      std::lock_guard<std::mutex> lock(imu_mutex);
      if (!imu.empty()) {
        const Timestamp from = std::max(imu_fed_until, std::max(imu.earliest(), t - kSecond));
        s = imu.between(from, t);
      }
    }
    if (s.empty()) return std::nullopt;
    predictor.add_samples(s);
    imu_fed_until = t;
    if (!gravity_known) return std::nullopt;
    if (tracker.state() == tracking::TrackingState::kInitializing) return std::nullopt;
    const auto p = predictor.predict(t);
    if (!p) return std::nullopt;
    predicted_v_w = p->v_w;
    const double since_bridge =
        last_bridge_t >= 0 && t >= last_bridge_t ? to_seconds(t - last_bridge_t) : -1.0;
    const InertialPriorSigmas sigmas =
        inertial_prior_sigmas(options, inertial_prior_age(p->since_fix_s, since_bridge));
    tracking::MotionPrior prior;
    prior.T_w_c = p->T_w_b * calib.T_body_camera;
    prior.rotation_sigma = sigmas.rotation_rad;
    prior.translation_sigma = sigmas.translation_m;
    return prior;
  }

  // The gyro's rotation since the newest keyframe, carried up to frame stamp t and handed to
  // the tracker: should this frame become a keyframe, local BA holds the two to it.
  void link_gyro(Timestamp t) {
    if (kf_gyro_from >= 0 && gyro_t > 0 && t > gyro_t) {
      std::optional<SO3> d;
      std::vector<ImuSample> s;
      {
        std::lock_guard<std::mutex> lock(imu_mutex);
        d = gyro_delta(imu, gyro_t, t, predictor.bias().gyro);
        if (d && kf_pre) s = imu.between(gyro_t, t);
      }
      // A pre-integration with a hole in it is no measurement: the keyframe gets none.
      if (kf_pre && (s.size() < 2 || !kf_pre->integrate(s, gyro_t, t))) kf_pre.reset();
      if (d) {
        kf_gyro_R = kf_gyro_R * *d;
        kf_gyro_dt += to_seconds(t - gyro_t);
      } else {
        kf_gyro_from = -1;  // a gap in the IMU: no link until the next keyframe
      }
    }
    gyro_t = t;
    if (kf_gyro_from < 0 || !options.gyro_links) {
      tracker.set_gyro_link(std::nullopt);
      return;
    }
    mapping::GyroLink link;
    link.from = kf_gyro_from;
    const Mat3 R_bc = calib.T_body_camera.rotation();
    link.R_c_from = (R_bc.transpose() * kf_gyro_R.matrix() * R_bc).transpose();
    link.dt_s = kf_gyro_dt;
    const double h = kf_gyro_dt;
    const double white = calib.imu.gyro_noise * calib.imu.gyro_noise * h;
    const double bias = predictor.gyro_bias_sigma() * h;
    const double rel = options.gyro_link_relative_sigma * kf_gyro_R.angle();
    link.sigma_rad = std::sqrt(white + bias * bias + rel * rel +
                               options.gyro_link_sigma_floor * options.gyro_link_sigma_floor);
    if (kf_pre && gravity_known && options.inertial_ba) {
      link.imu = kf_pre->summary();
      link.gravity = predictor.gravity();
      link.T_body_camera = calib.T_body_camera;
    }
    tracker.set_gyro_link(link);
  }

  // The gyro's rotation over dt seconds as a prior: its white noise, a floor and a share of the
  // angle turned (camera-IMU rotation error); SystemOptions::gyro_rotation_prior. Until the
  // bias has been measured once (a still start, or a first window of fixes), the prior also
  // counts the bias's initial uncertainty over dt: EuRoC V1_01's gyro reads 0.08 rad/s about z
  // at rest, and a prior that took the unknown bias as zero held its first second of vision
  // to a turning camera (APE 6.9 mm; 1.0 mm with the term, stereo alone 0.9).
  double gyro_prior_sigma(double dt, double angle) const {
    const double bias = predictor.gyro_bias_measured() ? 0.0 : predictor.gyro_bias_sigma() * dt;
    return calib.imu.gyro_noise * std::sqrt(dt) + bias + options.gyro_prior_sigma_floor +
           options.gyro_prior_relative_sigma * angle;
  }

  // Whether a frame features lost may be carried from the one before with the IMU's motion as
  // the prior (depth_carry below).
  bool may_carry(const RgbdFrame& frame, const Image& ref_depth, Timestamp t_prev) const {
    if (frame.depth.empty() || ref_depth.empty() || !prev_T_w_c || last_vision_t == 0 ||
        t_prev <= 0 || frame.t <= t_prev ||
        frame.t - last_vision_t > from_seconds(options.depth_carry_max_s)) {
      return false;
    }
    // The IMU's attitude and velocity must have agreed with vision before the loss: its
    // motion is all depth leaves unseen, and a wrong attitude turns gravity into an
    // acceleration the fixes would then carry on (uav-zigzag, 29 s, vision 8 degrees off and at
    // odds with the IMU: 5 m in 3 s, 13.6 m APE).
    if (recent_imu_chi2.size() < recent_imu_chi2_frames) return false;
    std::vector<double> chi2(recent_imu_chi2.begin(), recent_imu_chi2.end());
    std::nth_element(chi2.begin(), chi2.begin() + chi2.size() / 2, chi2.end());
    return chi2[chi2.size() / 2] <= options.depth_carry_max_imu_chi2;
  }

  static std::vector<tracking::PixelBox> mover_boxes(const std::vector<dynamic::BoxRegion>& boxes) {
    std::vector<tracking::PixelBox> movers;
    for (const auto& b : boxes) {
      if (!b.parked) movers.push_back({b.x_min, b.y_min, b.x_max, b.y_max});
    }
    return movers;
  }

  // The pose of a frame features lost, by aligning its depth to the previous frame's, with
  // corners followed from it (SystemOptions::corner_tracks) and the IMU's motion since then as
  // the prior (SystemOptions::depth_carry); none when depth cannot, and `refused` set when the
  // alignment moved the IMU's motion too far (depth_carry_max_correction_chi2).
  struct Carried {
    SE3 T_w_c;
    bool six_dof = false;  // depth and corner tracks fixed every direction, not the IMU
  };

  std::optional<Carried> depth_carry(const RgbdFrame& frame, const Image& ref_gray,
                                     const Image& cur_gray, const Image& ref_depth,
                                     double ref_scale, const SE3& predicted_T_w_c, Timestamp t_prev,
                                     const std::vector<dynamic::BoxRegion>& boxes, bool& refused) {
    refused = false;
    if (!options.depth_carry || !may_carry(frame, ref_depth, t_prev)) return std::nullopt;
    const auto t0 = Clock::now();
    const std::vector<tracking::PixelBox> movers = mover_boxes(boxes);
    tracking::CornerTracks corners;
    // Corners need depth on the grey image's own pixels (a registered depth image).
    if (options.corner_tracks && !ref_gray.empty() && ref_depth.width == ref_gray.width &&
        ref_depth.height == ref_gray.height && ref_scale > 0.0) {
      corners = tracking::follow_corners(ref_gray, ref_depth, ref_scale, cur_gray, calib.camera,
                                         options.corner_track_options, movers);
      stats.record("corner_tracks", ms_since(t0));
    }
    tracking::DepthAlignmentPrior prior;
    prior.T_ref_cur = prev_T_w_c->inverse() * predicted_T_w_c;
    const double dt = to_seconds(frame.t - t_prev);
    prior.rotation_sigma = gyro_prior_sigma(dt, prior.T_ref_cur.so3().angle());
    prior.translation_sigma = options.depth_carry_translation_sigma;
    const tracking::DepthAlignmentResult r =
        tracking::align_depth(ref_depth, ref_scale, frame.depth, frame.depth_scale, calib.camera,
                              prior, options.depth_alignment, movers, corners.tracks);
    stats.record("depth_carry", ms_since(t0));
    if (!r.ok) return std::nullopt;
    // How far depth moved the IMU's motion, in the prior's sigmas: far means a mover.
    const Vec6 e = (r.T_ref_cur * prior.T_ref_cur.inverse()).log();
    const double correction_chi2 =
        e.head<3>().squaredNorm() / (prior.translation_sigma * prior.translation_sigma) +
        e.tail<3>().squaredNorm() / (prior.rotation_sigma * prior.rotation_sigma);
    if (options.depth_carry_max_correction_chi2 > 0.0 &&
        correction_chi2 > options.depth_carry_max_correction_chi2) {
      refused = true;
      return std::nullopt;
    }
    return Carried{*prev_T_w_c * r.T_ref_cur,
                   r.weakest_information >= options.frame_to_frame_min_information};
  }

  // Vision's disagreement with the IMU's prediction, in the prediction's own sigmas.
  static double prior_chi2(const tracking::MotionPrior& p, const SE3& T_w_c) {
    const Vec6 e = (T_w_c.inverse() * p.T_w_c).log();
    if (!e.allFinite()) return -1.0;
    return e.head<3>().squaredNorm() / (p.translation_sigma * p.translation_sigma) +
           e.tail<3>().squaredNorm() / (p.rotation_sigma * p.rotation_sigma);
  }

  // SystemOptions::static_gyro_bias: the IMU buffer holds the last second.
  void set_static_gyro_bias(Timestamp t) {
    std::vector<ImuSample> s;
    {
      std::lock_guard<std::mutex> lock(imu_mutex);
      if (!imu.empty()) s = imu.between(std::max(imu.earliest(), t - kSecond), t);
    }
    imu::StaticInitOptions so;
    so.window_s = 0.25;
    so.min_still_s = 0.5;
    const imu::StaticInitResult r = imu::static_initialize(s, so);
    if (!r.ok()) return;
    // gyro_std is the spread of 0.1 s block means: the mean of n such blocks is that over √n.
    const double blocks = std::max(1.0, to_seconds(r.still_end - r.still_begin) / so.smoothing_s);
    predictor.set_gyro_bias(r.gyro_bias, std::max(r.gyro_std / std::sqrt(blocks), 1e-4));
    stats.count("imu.static_gyro_bias");
  }

  // Gravity in a world that is not gravity-aligned (no ground truth, no IMU before the first
  // frame: EuRoC's IMU starts with its first image, so does a live one): the specific force
  // rotated into the world, averaged over half a second of tracked frames, is -gravity as
  // long as the body does not accelerate for that long.
  void estimate_gravity(Timestamp t, const SE3& T_w_b) {
    ImuSample s;
    {
      std::lock_guard<std::mutex> lock(imu_mutex);
      if (!imu.at(t, &s)) return;
    }
    gravity_sum += T_w_b.so3() * s.acc;
    if (++gravity_samples < 15) return;
    const Vec3 g = -gravity_sum / gravity_samples;
    if (std::fabs(g.norm() - imu::kGravityMagnitude) < 0.5) {
      predictor.set_gravity(g.normalized() * imu::kGravityMagnitude);
      gravity_known = true;
      if (options.static_gyro_bias) set_static_gyro_bias(t);
    } else {
      gravity_sum.setZero();  // accelerating: try the next half second
      gravity_samples = 0;
    }
  }

  void ba_loop() {
    lower_this_thread_priority(options.background_nice);
    std::unique_lock<std::mutex> lock(ba_mutex);
    for (;;) {
      ba_cv.wait(lock, [&] { return tri_request || ba_request || ba_stop; });
      if (tri_request) {
        mapping::TriangulationProblem pb = std::move(*tri_request);
        tri_request.reset();
        ba_busy = true;
        lock.unlock();
        const auto t0 = Clock::now();
        TriangulationResult r{
            pb.current.id,
            mapping::solve_triangulation(pb, calib.camera, tracker.options().triangulation)};
        stats.record("mapping.triangulation", ms_since(t0));
        lock.lock();
        tri_results.push_back(std::move(r));
        ba_busy = false;
        ba_cv.notify_all();
        frames.wake();
        continue;
      }
      if (!ba_request) return;  // stopped, and nothing left to solve
      mapping::LocalBaProblem pb = std::move(*ba_request);
      ba_request.reset();
      ba_busy = true;
      lock.unlock();
      const auto t0 = Clock::now();
      mapping::LocalBaSolution sol =
          imu::solve_inertial_local_ba(pb, calib.camera, tracker.options().ba);
      stats.record("mapping.local_ba", ms_since(t0));
      lock.lock();
      ba_results.push_back(std::move(sol));
      ba_busy = false;
      ba_cv.notify_all();
      frames.wake();
    }
  }

  // Tracking thread (and finish()): writes what the local-mapping thread solved back into the
  // tracker's map. wait: until it has nothing left, the local BA a finished keyframe requests
  // included (lock-step runs, so that they stay reproducible).
  void apply_mapping_results(bool wait) {
    for (;;) {
      std::vector<TriangulationResult> tris;
      {
        std::unique_lock<std::mutex> lock(ba_mutex);
        if (wait) ba_cv.wait(lock, [&] { return !tri_request && !ba_request && !ba_busy; });
        tris.swap(tri_results);
      }
      // Solved local BAs first: they are of older keyframes.
      apply_local_ba_results();
      for (const TriangulationResult& r : tris) finish_keyframe(r);
      if (!wait || tris.empty()) return;
    }
  }

  void finish_keyframe(const TriangulationResult& r) {
    const auto t0 = Clock::now();
    std::vector<mapping::KeyframeId> culled;
    const bool finished = tracker.finish_keyframe(r.keyframe, r.points, culled);
    for (const mapping::KeyframeId id : culled) forget_place(id);
    keyframes_culled += culled.size();
    if (!finished) return;
    stats.record("mapping.keyframe_finish", ms_since(t0));
    const tracking::KeyframeCompletionTimes& ct = tracker.completion_times();
    stats.record("mapping.keyframe_finish.triangulation", ct.triangulation_ms);
    stats.record("mapping.keyframe_finish.connections", ct.connections_ms);
    stats.record("mapping.keyframe_finish.point_culling", ct.point_culling_ms);
    stats.record("mapping.keyframe_finish.keyframe_culling", ct.keyframe_culling_ms);
    stats.record("mapping.keyframe_finish.ba_gather", ct.ba_gather_ms);
    if (request_local_ba() != r.keyframe) loop_job_ready(r.keyframe);
  }

  // Hands the newest keyframe's triangulation to the local-mapping thread.
  void request_triangulation() {
    auto pb = tracker.take_triangulation();
    if (!pb) return;
    {
      std::lock_guard<std::mutex> lock(ba_mutex);
      // Replaces one not yet started: a keyframe forced in meanwhile (a relocalization)
      // completed that one without its points.
      tri_request = std::move(pb);
    }
    ba_cv.notify_all();
  }

  void apply_local_ba_results() {
    std::vector<mapping::LocalBaSolution> done;
    {
      std::lock_guard<std::mutex> lock(ba_mutex);
      done.swap(ba_results);
    }
    for (const auto& sol : done) {
      const auto t0 = Clock::now();
      ba_outliers += static_cast<std::size_t>(tracker.apply_local_ba(sol));
      stats.record("mapping.apply_local_ba", ms_since(t0));
      loop_job_ready(sol.current);
      // The keyframe's own frame reports the refined pose, as it does with inline BA.
      const mapping::Keyframe* kf = tracker.map().keyframe(sol.current);
      if (!kf) continue;
      const double t = to_seconds(kf->t);
      std::lock_guard<std::mutex> lock(result_mutex);
      for (std::size_t i = trajectory.size(); i-- > 0;) {
        if (trajectory.stamps[i] < t) break;
        if (trajectory.stamps[i] == t) {
          trajectory.poses[i] = kf->T_w_c * calib.T_body_camera.inverse();
          break;
        }
      }
    }
  }

  // Hands the newest keyframe's local BA to the local-mapping thread; returns its keyframe.
  mapping::KeyframeId request_local_ba() {
    auto pb = tracker.take_local_ba();
    if (!pb) return -1;
    const mapping::KeyframeId id = pb->current;
    mapping::KeyframeId superseded = -1;
    {
      std::lock_guard<std::mutex> lock(ba_mutex);
      if (ba_request) {
        ++ba_superseded;
        superseded = ba_request->current;
      }
      ba_request = std::move(pb);
    }
    ba_cv.notify_all();
    if (superseded >= 0) loop_job_ready(superseded);  // its BA will not come
    return id;
  }

  // A keyframe whose local BA is done (or dropped) goes on to place recognition.
  void loop_job_ready(mapping::KeyframeId id) {
    const auto it = std::find(awaiting_ba.begin(), awaiting_ba.end(), id);
    if (it == awaiting_ba.end()) return;
    awaiting_ba.erase(it);
    push_loop_job(id);
  }

  void forget_place(mapping::KeyframeId id) {
    std::erase(awaiting_ba, id);  // its BA result finds no keyframe
    restart_keyframes.erase(id);
    if (!loop_detector) return;
    LoopJob job;
    job.view.id = id;
    job.forget = true;
    loop_jobs.push(std::move(job));
  }

  void push_loop_job(mapping::KeyframeId id) {
    const auto restart = restart_keyframes.find(id);
    const bool after_restart = restart != restart_keyframes.end();
    const bool attitude_held = after_restart && restart->second;
    if (after_restart) restart_keyframes.erase(restart);
    if (!loop_detector) return;
    const mapping::Keyframe* kf = tracker.map().keyframe(id);
    if (!kf) return;
    LoopJob job;
    job.after_restart = after_restart;
    job.attitude_held = attitude_held;
    job.t = kf->t;
    job.T_w_c = kf->T_w_c;
    job.view = loop::place_view(kf->id, kf->features, tracker.map().covisible(kf->id, 10));
    loop_jobs.push(std::move(job));
  }

  void process(QueuedFrame& q) {
    const RgbdFrame& frame = q.frame;
    FrameReport report;
    report.t = frame.t;

    // Features first: they need no boxes, and the detection thread works on this frame
    // meanwhile. Waiting for the boxes first put detection and extraction end to end on the
    // frame's latency (cafe --realtime: 7.2 ms waited, then 6.5 ms extracted).
    auto t0 = Clock::now();
    tracking::FrameFeatures features;
    if (!q.right.empty()) {
      features = process_stereo(q);
    } else {
      const LastMoverMasks m =
          last_mover_masks(last_boxes, prev_depth, prev_depth_scale, frame.color.width,
                           frame.color.height, options.mover_budget_margin_px,
                           options.mover_silhouettes, options.mover_silhouette, options.dynamic);
      features = tracker.extractor().extract(frame, m.silhouette.empty() ? nullptr : &m.silhouette,
                                             m.movers.empty() ? nullptr : &m.movers);
    }
    stats.record("features", ms_since(t0));
    report.features = static_cast<int>(features.size());

    // Boxes for this frame.
    std::vector<dynamic::BoxRegion> boxes;
    std::vector<detect::Detection> dynamic_dets, static_dets;
    std::vector<bool> parkable;  // per box: a vehicle, which may park
    if (detector) {
      t0 = Clock::now();
      const auto set = options.sequential
                           ? detections.wait_and_match(frame.t, std::chrono::seconds(30))
                           : detections.wait_and_match(frame.t, std::chrono::milliseconds(30));
      stats.record("detection_wait", ms_since(t0));
      if (set) {
        detect::DetectionRoles roles =
            detect::split_by_role(set->boxes, dynamic_classes, options.mover_min_score);
        dynamic_dets = std::move(roles.movers);
        static_dets = std::move(roles.objects);
      }
      // Movers whose detection this frame misses (or that no detection matched) keep a box.
      std::vector<detect::Detection> carried =
          box_coaster.update(frame.t, dynamic_dets, frame.color.width, frame.color.height);
      stats.count("detection.carried_boxes", carried.size());
      for (auto& d : carried) dynamic_dets.push_back(std::move(d));
      for (const auto& d : dynamic_dets) boxes.push_back({d.x_min, d.y_min, d.x_max, d.y_max});
      detections.tracked_up_to(frame.t);
      for (const auto& d : dynamic_dets)
        parkable.push_back(options.park_vehicles && parkable_classes.is_dynamic_class(d.label));
      if (options.park_vehicles) {
        parked_boxes.assign(frame.t, boxes, parkable);
        // Boxes (one per frame) of vehicles taken as parked: scenery for tracking and the maps.
        stats.count("detection.parked_boxes",
                    static_cast<std::size_t>(std::count_if(
                        boxes.begin(), boxes.end(), [](const auto& b) { return b.parked; })));
      }
    }
    report.detections = static_cast<int>(boxes.size());
    report.boxes = boxes;
    last_boxes = boxes;

    if (inertial) {
      t0 = Clock::now();
      wait_for_imu(frame.t);
      stats.record("imu_wait", ms_since(t0));
    }

    if (!world_initialized) initialize_world(frame.t);
    apply_mapping_results(options.sequential);
    const std::optional<tracking::MotionPrior> prior = inertial_prediction(frame.t);

    // Dynamic filter against the previous frame.
    t0 = Clock::now();
    const Image gray = to_gray(frame.color);
    std::vector<std::uint8_t> keep(features.size(), 1);
    std::vector<Vec2> pts;
    pts.reserve(features.size());
    for (const auto& kp : features.keypoints) pts.push_back(kp.px);
    dynamic::DynamicFilterResult r;
    dynamic::FlowPyramid cur_pyramid;
    // The first frame keeps every feature, those in boxes too. Dropping the box features there
    // (boxes alone deciding, as when too little background is seen) was measured: on market's
    // first frame it removes 335 of the 344 walker features, yet the 60 s runs came out worse
    // on all three draws (APE 0.134 -> 0.852, 0.181 -> 0.237, 0.126 -> 0.209 m; cafe and
    // uav-zigzag unchanged, their first frames hold no detection). The next frames then track
    // on fewer inliers (99 -> 80, 140 -> 77 on market seed 3); why whole runs lose, not found.
    if (!prev_gray.empty() && options.dynamic.mode != dynamic::FilterMode::kOff) {
      dynamic::DynamicFilterInput in;
      in.prev_gray = &prev_gray;
      in.cur_gray = &gray;
      in.points = pts;
      in.boxes = boxes;
      // The filter is the only reader of the sensor's raw depth: keyframes need not keep it.
      in.depth_m = std::move(features.sensor_depth);
      in.prev_depth = prev_depth.empty() ? nullptr : &prev_depth;
      in.depth_scale = prev_depth_scale;
      in.cur_depth = frame.depth.empty() ? nullptr : &frame.depth;
      in.depth_range_m = calib.depth_max.value_or(0.0);
      in.K = calib.camera.K();
      in.prev_pyramid = &prev_pyramid;
      in.cur_pyramid_out = &cur_pyramid;
      in.prev_trail = &prev_trail;
      {
        std::lock_guard<std::mutex> lock(imu_mutex);
        if (inertial) in.R_cur_prev = gyro_rotation(imu, prev_t, frame.t, calib.T_body_camera);
      }
      if (in.R_cur_prev && prior && prev_T_w_c && options.dynamic_motion_prior) {
        // The camera's translation since the previous frame, as the IMU predicts it: the filter
        // checks its ego-motion against it (a crowd moving with the camera is a consensus too).
        in.t_cur_prev = (prior->T_w_c.inverse() * *prev_T_w_c).translation();
        in.prior_translation_sigma_m = prior->translation_sigma;
        in.prior_rotation_sigma_rad = prior->rotation_sigma;
      }
      r = dynamic::classify_features(in, options.dynamic);
      prev_trail = std::move(r.trail);
      if (options.park_vehicles) parked_boxes.observe(r);
      for (std::size_t i = 0; i < keep.size(); ++i) {
        keep[i] = r.labels[i] != dynamic::FeatureLabel::kDynamic;
      }
      report.dynamic_features = static_cast<int>(r.count(dynamic::FeatureLabel::kDynamic));
    } else {
      r.labels.assign(pts.size(), dynamic::FeatureLabel::kStatic);
      prev_trail = {};
    }
    stats.record("dynamic_filter", ms_since(t0));
    {
      std::lock_guard<std::mutex> lock(imu_mutex);
      imu.drop_before(frame.t - kSecond);
    }
    const Image ref_gray = prev_gray;  // shared pixels, for the corner tracks of depth carry
    prev_gray = gray;
    prev_pyramid = std::move(cur_pyramid);
    const Image ref_depth = prev_depth;  // the previous frame's, for depth carry
    const double ref_depth_scale = prev_depth_scale;
    prev_depth = frame.depth;  // shared pixels, not a copy
    prev_depth_scale = frame.depth_scale;
    const Timestamp frame_t_prev = prev_t;
    prev_t = frame.t;

    report.feature_px.reserve(features.size());
    for (const auto& kp : features.keypoints) report.feature_px.push_back(kp.px);
    report.feature_dynamic.resize(keep.size());
    for (std::size_t i = 0; i < keep.size(); ++i) report.feature_dynamic[i] = keep[i] ? 0 : 1;

    std::optional<SE3> predicted;
    if (prior) predicted = prior->T_w_c;
    std::optional<SO3> attitude;
    if (!prior && inertial && gravity_known) {
      if (const auto a = predictor.attitude()) {
        attitude = a->R_w_b * calib.T_body_camera.so3();
      }
    }
    tracker.set_attitude_hint(attitude);
    if (inertial) link_gyro(frame.t);
    if (inertial && options.gyro_rotation_prior && prev_tracked && prev_T_w_c && frame_t_prev > 0 &&
        frame.t > frame_t_prev) {
      std::optional<SO3> d;
      {
        std::lock_guard<std::mutex> lock(imu_mutex);
        d = gyro_delta(imu, frame_t_prev, frame.t, predictor.bias().gyro);
      }
      if (d) {
        const SO3 R_bc = calib.T_body_camera.so3();
        const SO3 R_prev_cur = R_bc.inverse() * *d * R_bc;  // camera frame
        const double dt = to_seconds(frame.t - frame_t_prev);
        tracker.set_rotation_prior(prev_T_w_c->so3() * R_prev_cur,
                                   gyro_prior_sigma(dt, R_prev_cur.angle()));
      }
    }
    tracker.set_body_velocity(options.inertial_ba ? predicted_v_w : std::nullopt);
    // Live, with frames queued behind this one, a lost track must not search the whole map on
    // every frame: that search is what let latency pile up to seconds on long market runs.
    // Lock-step runs have all the time they need (and stay reproducible).
    tracker.set_busy(!options.sequential && frames.size() > 0);
    // During a frame-to-frame stretch the frame is aligned first, and the bridge held back only
    // for a frame that alignment tracks (SystemOptions::bridge_where_alignment_fails).
    std::optional<Carried> early_carry;
    bool early_refused = false;
    const bool hold = prev_frame_to_frame && options.frame_to_frame_holds_bridge;
    const bool align_first = hold && options.bridge_where_alignment_fails && predicted.has_value();
    if (align_first) {
      early_carry = depth_carry(frame, ref_gray, gray, ref_depth, ref_depth_scale, *predicted,
                                frame_t_prev, boxes, early_refused);
    }
    tracker.set_hold_bridge(hold && (!align_first || (early_carry && early_carry->six_dof)));
    if (prev_frame_to_frame) tracker.set_prior_gate_chi2(options.frame_to_frame_gate_chi2);
    t0 = Clock::now();
    const tracking::TrackResult tr =
        prior && (options.inertial_prior || options.inertial_gate_chi2 > 0.0)
            ? tracker.track(std::move(features), *prior, &keep)
            : tracker.track(std::move(features), predicted, &keep);
    stats.record("tracking", ms_since(t0));
    if (tr.bridged && !tr.restarted) last_bridge_t = frame.t;
    if (tr.new_keyframe && tr.bridged) {
      restart_keyframes[tr.keyframe_id] = predicted.has_value() || attitude.has_value();
    }
    if (tr.new_keyframe) {
      kf_gyro_from = tr.keyframe_id;
      kf_gyro_R = SO3();
      kf_gyro_dt = 0.0;
      if (options.inertial_ba) kf_pre.emplace(predictor.bias(), calib.imu);
    }
    const mapping::KeyframeId local_ba_requested = request_local_ba();
    request_triangulation();
    if (inertial) {
      const SE3 T_w_b = tr.T_w_c * calib.T_body_camera.inverse();
      // A relocalized pose is not continuous with the fixes before the loss. While the IMU
      // still carries the body (a short loss), its velocity is: the predictor restarts from the
      // relocalized pose with it, so the next frames keep their prediction (the filter's motion
      // prior, the tracker's gate) instead of waiting for a new velocity window. Without one,
      // a walker filling the view right after a relocalization took over the track (uav-zigzag,
      // 3.7 s: 13 of 934 mover features removed, the tracker locked onto the walker).
      const bool relocalized = tr.state == tracking::TrackingState::kRelocalized;
      // Only a velocity fitted to vision lately is carried: reanchors chained through a flaky
      // track (lost, relocalized, lost again) carried the IMU's own drift on and on
      // (uav-zigzag seed 2: 900 m off after 20 s).
      const auto fitted_at = predictor.velocity_fitted_at();
      const bool velocity_recent =
          fitted_at && frame.t - *fitted_at <= from_seconds(options.reanchor_velocity_max_age_s);
      if (relocalized && predicted_v_w && options.reanchor_on_relocalization && velocity_recent) {
        predictor.reanchor(frame.t, T_w_b, *predicted_v_w);
      } else if ((relocalized || tr.state == tracking::TrackingState::kOk) &&
                 !(tr.bridged && !tr.restarted)) {
        // A bridge's pose is the IMU's own prediction: as a fix it would restart the dead
        // reckoning clock (max_gap_s) with nothing seen, and a track that lost the new local map
        // at once bridged again and again, the IMU alone carrying it (uav-zigzag seed 2: 900 m
        // off after 20 s). The frames tracked after it are fixes again.
        // A restart without a prediction jumps too: its pose is the last one, not where the body
        // is.
        if (relocalized || tr.restarted) predictor.clear_fixes();
        predictor.add_fix(frame.t, T_w_b);
        if (!gravity_known) estimate_gravity(frame.t, T_w_b);
      }
    }
    stats.record("tracking.match", tr.times.match_ms);
    stats.record("tracking.optimize", tr.times.optimize_ms);
    if (tr.new_keyframe) stats.record("mapping.keyframe", tr.times.keyframe_ms);

    report.state = tr.state;
    report.inliers = tr.inliers;
    report.local_points = tr.local_points;
    report.visible_points = tr.visible_points;
    report.keyframe = tr.new_keyframe;
    report.T_w_body = tr.T_w_c * calib.T_body_camera.inverse();
    if (prior && tr.state != tracking::TrackingState::kLost) {
      report.imu_chi2 = prior_chi2(*prior, tr.T_w_c);
      if (!tr.bridged) {
        recent_imu_chi2.push_back(report.imu_chi2);
        if (recent_imu_chi2.size() > recent_imu_chi2_frames) recent_imu_chi2.pop_front();
      }
    }
    if (tr.state == tracking::TrackingState::kOk ||
        tr.state == tracking::TrackingState::kRelocalized) {
      report.source = tr.bridged          ? PoseSource::kBridged
                      : tr.prior_conflict ? PoseSource::kVisionImu
                                          : PoseSource::kVision;
    }
    std::optional<SE3> depth_T_w_c;
    bool six_dof = false;
    if (tr.state == tracking::TrackingState::kLost && predicted) {
      bool refused = early_refused;
      const auto c = align_first ? early_carry
                                 : depth_carry(frame, ref_gray, gray, ref_depth, ref_depth_scale,
                                               *predicted, frame_t_prev, boxes, refused);
      if (refused) ++depth_carry_refused;
      if (c) {
        depth_T_w_c = c->T_w_c;
        six_dof = c->six_dof;
      }
    }
    if (depth_T_w_c) {
      report.T_w_body = *depth_T_w_c * calib.T_body_camera.inverse();
      report.source = six_dof ? PoseSource::kFrameToFrame : PoseSource::kDepthImu;
      predictor.add_fix(frame.t, report.T_w_body);
    } else if (tr.state == tracking::TrackingState::kLost && predicted) {
      // Lost, but the IMU still knows where the body is (for max_gap_s).
      report.T_w_body = *predicted * calib.T_body_camera.inverse();
      report.inertial_only = true;
      report.source = PoseSource::kImu;
    }
    prev_frame_to_frame = six_dof;
    prev_tracked = (tr.state == tracking::TrackingState::kOk ||
                    tr.state == tracking::TrackingState::kRelocalized) &&
                   !tr.bridged;
    if (tr.state == tracking::TrackingState::kOk ||
        tr.state == tracking::TrackingState::kRelocalized) {
      prev_T_w_c = tr.T_w_c;
      last_vision_t = frame.t;
    } else if (depth_T_w_c) {
      prev_T_w_c = depth_T_w_c;
    } else if (predicted) {
      prev_T_w_c = predicted;
    } else {
      prev_T_w_c.reset();
    }
    report.latency_ms = ms_since(q.arrival);
    stats.record("frame_latency", report.latency_ms);
    if (truth) {
      // Scoring against the ground-truth masks (reading them from disk) is evaluation, no part
      // of the filter or of the pose: it comes after the pose's latency is taken.
      t0 = Clock::now();
      report.removal = dynamic::count_removal(pts, r.labels, truth(frame.t),
                                              r.reasons.empty() ? nullptr : &r.reasons);
      stats.record("truth_masks", ms_since(t0));
    }
    {
      std::lock_guard<std::mutex> lock(result_mutex);
      if (report.lost()) ++lost;
      if (report.inertial_only) ++inertial_frames;
      if (depth_T_w_c && !six_dof) ++depth_frames;
      if (six_dof) ++frame_to_frame_frames;
      if (tr.bridged) ++bridged;
      if (tr.restarted) ++restarted;
      if (tr.prior_conflict) ++prior_conflicts;
      if (tr.relocalization_rejected) ++relocalizations_rejected;
      if (tr.global_search_skipped) ++relocalizations_deferred;
      if (tr.state != tracking::TrackingState::kLost || report.inertial_only || depth_T_w_c) {
        trajectory.push_back(to_seconds(frame.t), report.T_w_body);
      }
      removal += report.removal;
    }
    for (const mapping::KeyframeId id : tr.culled_keyframes) forget_place(id);
    keyframes_culled += tr.culled_keyframes.size();
    if (tr.new_keyframe) {
      // Place recognition sees the keyframe after its local BA (it anchors loop corrections).
      if (local_ba_requested == tr.keyframe_id || tracker.keyframe_pending(tr.keyframe_id)) {
        awaiting_ba.push_back(tr.keyframe_id);
      } else {
        push_loop_job(tr.keyframe_id);
      }
    }
    if (tr.new_keyframe && !frame.depth.empty()) {
      MappingJob job;
      job.keyframe_id = tr.keyframe_id;
      job.t = frame.t;
      job.T_w_c = tr.T_w_c;
      job.frame = frame;
      // Movers never reach the maps: detected dynamic-class boxes and a patch around every
      // feature the filter rejected (movers no detector caught) are masked out.
      // Parked vehicles are scenery: mapped, and objects for the database.
      for (std::size_t k = 0; k < boxes.size(); ++k) {
        const auto& b = boxes[k];
        if (b.parked) {
          static_dets.push_back(std::move(dynamic_dets[k]));
          continue;
        }
        job.masked.push_back({static_cast<int>(b.x_min), static_cast<int>(b.y_min),
                              static_cast<int>(b.x_max) + 1, static_cast<int>(b.y_max) + 1});
        // A vehicle removes the object under its box only when its own features, judged in
        // 3D, mostly moved: one too far to judge (no depth, too few features) may be the parked
        // car the database holds, and a box judged moving from its 2D flow may be the
        // background's it holds (the object in front stands still).
        const bool seen_moving = k < r.box_features.size() &&
                                 r.box_features[k] >= options.parked.min_features &&
                                 r.box_violating[k] > r.box_features[k] / 2;
        if (!parkable[k] || seen_moving) job.moving_boxes.push_back(std::move(dynamic_dets[k]));
      }
      for (std::size_t i = 0; i < report.feature_px.size(); ++i) {
        if (!report.feature_dynamic[i]) continue;
        const int u = static_cast<int>(report.feature_px[i].x());
        const int v = static_cast<int>(report.feature_px[i].y());
        job.masked.push_back(
            {u - kRejectedPatch, v - kRejectedPatch, u + kRejectedPatch, v + kRejectedPatch});
      }
      job.static_boxes = std::move(static_dets);
      const auto tq = Clock::now();
      mapping_jobs.push(std::move(job));
      stats.record("mapping.queue_wait", ms_since(tq));
    }
    for (Observer* o : observers) o->on_frame(report);
  }

  void mapping_loop() {
    lower_this_thread_priority(options.background_nice);
    while (auto job = mapping_jobs.pop()) {
      const RgbdFrame& f = job->frame;
      const std::vector<std::uint8_t> mask =
          maps::static_mask_from_boxes(f.depth.width, f.depth.height, job->masked);
      auto t0 = Clock::now();
      if (!last_dense_t || to_seconds(job->t - *last_dense_t) >= options.dense_map_interval_s) {
        maps::MapKeyframe mk;
        mk.T_w_c = job->T_w_c;
        mk.color = &f.color;
        mk.depth = &f.depth;
        mk.depth_scale = f.depth_scale;
        mk.camera = calib.camera;
        mk.static_mask = &mask;
        map_builder.insert(mk);
        last_dense_t = job->t;
        stats.record("mapping.dense", ms_since(t0));
      } else {
        stats.count("mapping.dense_skipped");
      }
      t0 = Clock::now();
      semantic::ObjectKeyframe ok;
      ok.keyframe_id = job->keyframe_id;
      ok.T_w_c = job->T_w_c;
      ok.stamp = job->t;
      ok.depth = &f.depth;
      ok.depth_scale = f.depth_scale;
      ok.camera = calib.camera;
      ok.static_mask = &mask;
      ok.static_boxes = std::move(job->static_boxes);
      ok.moving_boxes = std::move(job->moving_boxes);
      const semantic::ObjectUpdateStats os = objects.update(ok);
      stats.record("mapping.objects", ms_since(t0));
      // How the database changed its mind (timing.json counters): objects removed by a moving
      // box, seen moving by their own measurements, back where they stopped, gone from their
      // place, lost while moving.
      stats.count("objects.removed_moving", static_cast<std::size_t>(os.removed_moving));
      stats.count("objects.started_moving", static_cast<std::size_t>(os.started_moving));
      stats.count("objects.stopped", static_cast<std::size_t>(os.stopped));
      stats.count("objects.removed_absent", static_cast<std::size_t>(os.removed_absent));
      stats.count("objects.lost_moving", static_cast<std::size_t>(os.lost_moving));
      report_objects(job->t, job->keyframe_id);
    }
  }

  // Observers (e.g. the agent's object telemetry) see the database as it changes, not only in
  // objects.json after the run. Observers are registered before the first feed, so reading the
  // list here needs no lock.
  void report_objects(Timestamp t, std::int64_t keyframe_id) {
    if (observers.empty()) return;
    ObjectsReport r;
    r.t = t;
    r.keyframe_id = keyframe_id;
    r.objects = objects.objects();
    for (Observer* o : observers) o->on_objects(r);
  }

  void loop_loop() {
    lower_this_thread_priority(options.background_nice);
    std::optional<loop::PoseId> previous;
    while (auto job = loop_jobs.pop()) {
      if (job->forget) {
        loop_detector->erase(job->view.id);
        continue;
      }
      const loop::PoseId id = job->view.id;
      keyframe_poses[id] = job->T_w_c;
      keyframe_stamps[id] = job->t;
      if (previous) {
        graph_edges.push_back(loop::odometry_edge(*previous, id,
                                                  keyframe_poses[*previous].inverse() * job->T_w_c,
                                                  options.pose_graph_sigmas));
      }
      previous = id;
      const auto t0 = Clock::now();
      if (job->after_restart) restarts.insert(id);
      if (job->after_restart && !job->attitude_held) blind_restarts.insert(id);
      const auto match = loop_detector->process(job->view);
      stats.record("loop.detect", ms_since(t0));
      if (match) {
        const loop::LoopGateResult gate = loop::check_loop_drift(
            keyframe_poses, match->match, match->query, match->T_match_query, options.loop_gate);
        if (!loop::accept_loop(
                gate, loop::restart_span(restarts, blind_restarts, match->match, match->query))) {
          ++loops_rejected;
          continue;
        }
        ++loops;
        graph_edges.push_back(loop::loop_edge(match->match, match->query, match->T_match_query,
                                              options.pose_graph_sigmas));
      }
    }
  }

  // After a loop: optimize the keyframe pose graph, then move every frame pose with the
  // correction of the keyframe before it, and the objects with their keyframes.
  void correct_with_loops() {
    if (loops == 0 || keyframe_poses.size() < 3) return;
    const auto t0 = Clock::now();
    const loop::PoseGraphResult r =
        loop::optimize_pose_graph(keyframe_poses, graph_edges, {keyframe_poses.begin()->first});
    stats.record("loop.pose_graph", ms_since(t0));
    if (!r.converged && r.final_cost >= r.initial_cost) return;
    std::map<Timestamp, SE3> correction;  // by keyframe stamp: T_w_new * T_w_old^-1
    for (const auto& [id, T_new] : r.poses) {
      correction[keyframe_stamps[id]] = T_new * keyframe_poses[id].inverse();
      objects.reanchor(id, T_new);
    }
    report_objects(keyframe_stamps.rbegin()->second, -1);
    std::lock_guard<std::mutex> lock(result_mutex);
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
      const Timestamp t = from_seconds(trajectory.stamps[i]);
      auto it = correction.upper_bound(t);
      if (it == correction.begin()) continue;
      --it;
      trajectory.poses[i] = it->second * trajectory.poses[i];
    }
  }

  // The world frame: gravity-aligned (z up) from the accelerometer at the first frame when
  // there is an IMU, as DESIGN.md asks; otherwise the first camera pose.
  void initialize_world(Timestamp t) {
    world_initialized = true;
    if (options.initial_T_w_body) {
      if (const auto T_w_b = options.initial_T_w_body(t)) {
        tracker.set_initial_pose(*T_w_b * calib.T_body_camera);
        gravity_known = true;  // ground truth worlds are z up
        return;
      }
    }
    if (!calib.has_imu) return;
    std::vector<ImuSample> s;
    {
      std::lock_guard<std::mutex> lock(imu_mutex);
      s = imu.between(t - 200'000'000, t);
    }
    if (s.size() < 5) return;
    Vec3 acc = Vec3::Zero();
    for (const auto& x : s) acc += x.acc;
    acc /= static_cast<double>(s.size());
    if (acc.norm() < 5.0) return;  // not a plausible gravity reading
    const Quat R_w_b = Quat::FromTwoVectors(acc.normalized(), Vec3::UnitZ());
    tracker.set_initial_pose(SE3(R_w_b, Vec3::Zero()) * calib.T_body_camera);
    gravity_known = true;
  }
};

System::System(const Calibration& calib, SystemOptions options,
               std::unique_ptr<detect::Detector> detector)
    : impl_(std::make_unique<Impl>(calib, std::move(options), std::move(detector))) {
  impl_->tracking_thread = std::thread([this] { impl_->tracking_loop(); });
  if (impl_->detector) impl_->detection_thread = std::thread([this] { impl_->detection_loop(); });
  impl_->mapping_thread = std::thread([this] { impl_->mapping_loop(); });
  if (!impl_->tracker.options().inline_mapping) {
    impl_->ba_thread = std::thread([this] { impl_->ba_loop(); });
  }
  const std::string voc = impl_->options.vocabulary;
  if (!voc.empty() && std::filesystem::exists(voc)) {
    impl_->vocabulary = std::make_unique<loop::Vocabulary>(loop::Vocabulary::load(voc));
    impl_->loop_detector =
        std::make_unique<loop::LoopDetector>(*impl_->vocabulary, impl_->calib.camera);
    impl_->loop_thread = std::thread([this] { impl_->loop_loop(); });
  }
}

System::~System() { finish(); }

void System::add_observer(Observer* observer) { impl_->observers.push_back(observer); }
void System::set_truth_masks(TruthMaskProvider provider) { impl_->truth = std::move(provider); }

void System::feed(const Measurement& m) {
  if (const auto* imu = std::get_if<ImuSample>(&m)) {
    {
      std::lock_guard<std::mutex> lock(impl_->imu_mutex);
      impl_->imu.add(*imu);
    }
    impl_->imu_cv.notify_all();
    return;
  }
  {
    // Frames arrive in time order with the IMU: once one is fed, no IMU sample older than it
    // will come (wait_for_imu stops waiting for the frames before it).
    std::lock_guard<std::mutex> lock(impl_->imu_mutex);
    if (const auto* f = std::get_if<RgbdFrame>(&m)) {
      impl_->newest_frame_fed = std::max(impl_->newest_frame_fed, f->t);
    } else if (const auto* s = std::get_if<StereoFrame>(&m)) {
      impl_->newest_frame_fed = std::max(impl_->newest_frame_fed, s->t);
    }
  }
  impl_->imu_cv.notify_all();
  if (const auto* f = std::get_if<RgbdFrame>(&m)) {
    if (impl_->detector) impl_->detection_frames.push(*f);
    impl_->frames.push(QueuedFrame{*f, Clock::now(), Image{}});
  }
  if (const auto* s = std::get_if<StereoFrame>(&m)) {
    RgbdFrame left;
    left.t = s->t;
    left.color = s->left;
    left.source = s->source;
    if (impl_->detector) impl_->detection_frames.push(left);
    impl_->frames.push(QueuedFrame{std::move(left), Clock::now(), s->right});
  }
}

void System::finish() {
  if (impl_->finished.exchange(true)) return;
  {
    std::lock_guard<std::mutex> lock(impl_->imu_mutex);
    impl_->input_closed = true;
  }
  impl_->imu_cv.notify_all();
  impl_->detection_frames.close();
  impl_->frames.close();
  if (impl_->tracking_thread.joinable()) impl_->tracking_thread.join();
  if (impl_->ba_thread.joinable()) {
    // The tracking thread is done: the map is this thread's. The last keyframe's points and
    // local BA go in before the maps are written.
    impl_->apply_mapping_results(true);
    {
      std::lock_guard<std::mutex> lock(impl_->ba_mutex);
      impl_->ba_stop = true;
    }
    impl_->ba_cv.notify_all();
    impl_->ba_thread.join();
    impl_->apply_mapping_results(false);
    for (const mapping::KeyframeId id : std::vector<mapping::KeyframeId>(impl_->awaiting_ba)) {
      impl_->loop_job_ready(id);
    }
    std::lock_guard<std::mutex> lock(impl_->ba_mutex);
    impl_->stats.set_counter("mapping.local_ba_superseded", impl_->ba_superseded);
    impl_->stats.set_counter("mapping.local_ba_outliers", impl_->ba_outliers);
  }
  impl_->mapping_jobs.close();
  impl_->loop_jobs.close();
  if (impl_->mapping_thread.joinable()) impl_->mapping_thread.join();
  if (impl_->loop_thread.joinable()) impl_->loop_thread.join();
  impl_->correct_with_loops();
  impl_->stats.set_counter("loop.closed", impl_->loops);
  impl_->stats.set_counter("loop.rejected", impl_->loops_rejected);
  if (impl_->detection_thread.joinable()) impl_->detection_thread.join();
  impl_->stats.set_counter("detection.dropped", impl_->detection_frames.dropped());
  impl_->stats.set_counter("detection.matched", impl_->detections.matched());
  impl_->stats.set_counter("detection.missed", impl_->detections.missed());
  impl_->stats.set_counter("detection.late", impl_->detections.late());
  impl_->stats.set_counter("imu.rejected", impl_->imu.rejected());
  impl_->stats.set_counter("frames.lost", frames_lost());
  impl_->stats.set_counter("frames.inertial_only", impl_->inertial_frames);
  impl_->stats.set_counter("frames.depth_imu", impl_->depth_frames);
  impl_->stats.set_counter("frames.frame_to_frame", impl_->frame_to_frame_frames);
  impl_->stats.set_counter("frames.depth_carry_refused", impl_->depth_carry_refused);
  impl_->stats.set_counter("tracking.bridged", impl_->bridged);
  impl_->stats.set_counter("tracking.restarted", impl_->restarted);
  impl_->stats.set_counter("tracking.imu_conflicts", impl_->prior_conflicts);
  impl_->stats.set_counter("tracking.relocalizations_rejected", impl_->relocalizations_rejected);
  impl_->stats.set_counter("tracking.relocalizations_deferred", impl_->relocalizations_deferred);
  // Threads joined: the map is the tracker's alone. What a long run's memory grows with.
  impl_->stats.set_counter("map.keyframes", impl_->tracker.map().num_keyframes());
  impl_->stats.set_counter("map.points", impl_->tracker.map().num_points());
  impl_->stats.set_counter("map.keyframes_culled", impl_->keyframes_culled);
  {
    std::lock_guard<std::mutex> lock(impl_->imu_mutex);
    impl_->stats.set_counter("imu.missing", impl_->imu_missing ? 1 : 0);
  }
}

void System::write_map_outputs(const std::string& dir) const {
  const mapping::Map& map = impl_->tracker.map();
  mapping::save_map(dir + "/map.bin", map);
  mapping::write_keyframes_tum(dir + "/keyframes.txt", map, impl_->calib.T_body_camera);
  mapping::write_points_ply(dir + "/sparse.ply", map);
  // Dense cloud, OctoMap, 2D grid and objects (written after finish(): the thread is joined).
  impl_->map_builder.write_outputs(dir);
  impl_->objects.write_outputs(dir);
}

Trajectory System::trajectory() const {
  std::lock_guard<std::mutex> lock(impl_->result_mutex);
  return impl_->trajectory;
}
dynamic::RemovalCounts System::removal() const {
  std::lock_guard<std::mutex> lock(impl_->result_mutex);
  return impl_->removal;
}
const StageStats& System::stats() const { return impl_->stats; }
std::size_t System::frames_lost() const {
  std::lock_guard<std::mutex> lock(impl_->result_mutex);
  return impl_->lost;
}

}  // namespace kestrel::pipeline
