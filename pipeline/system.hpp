#pragma once
// The running SLAM system (DESIGN.md "Data flow of one frame"). Fed time-ordered measurements;
// owns the threads:
//   detection thread: frame -> Detector -> DetectionBuffer (newest wins when it falls behind)
//   tracking thread : waits for the IMU to pass the frame's stamp; IMU since last frame ->
//                     pose prediction (imu::InertialPredictor); features -> dynamic filter
//                     (boxes matched by stamp, flow, epipolar, homography/IMU) -> static
//                     features -> tracker (pose, keyframes, map) -> observers
//   local-mapping thread: local BA of each new keyframe on a copy of its window
//   mapping thread  : dense maps and objects per keyframe
//   loop thread     : place recognition per keyframe; the pose graph when the run ends
// `sequential` runs every stage in lock-step so tests are reproducible: the tracker waits for
// the detection of its own frame and for the local BA of the keyframe before.
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "core/calibration.hpp"
#include "core/frame.hpp"
#include "core/trajectory.hpp"
#include "detect/box_coasting.hpp"
#include "detect/detector.hpp"
#include "detect/dynamic_classes.hpp"
#include "dynamic/dynamic_filter.hpp"
#include "dynamic/mover_silhouette.hpp"
#include "dynamic/parked_boxes.hpp"
#include "dynamic/removal_metrics.hpp"
#include "imu/inertial_predictor.hpp"
#include "loop/edge_sigmas.hpp"
#include "loop/loop_gate.hpp"
#include "pipeline/mover_mask.hpp"
#include "pipeline/stage_stats.hpp"
#include "semantic/object_database.hpp"
#include "tracking/corner_tracks.hpp"
#include "tracking/depth_alignment.hpp"
#include "tracking/tracker.hpp"

namespace kestrel::pipeline {

struct SystemOptions {
  bool sequential = false;
  dynamic::DynamicFilterOptions dynamic;
  tracking::TrackerOptions tracker;
  Timestamp detection_tolerance_ns = 50'000'000;  // boxes match a frame within 50 ms
  std::size_t frame_queue = 8;
  std::size_t detection_queue = 2;
  std::vector<std::string> dynamic_classes;        // empty: detect/dynamic_classes defaults
  float mover_min_score = detect::kMoverMinScore;  // weaker dynamic-class boxes are dropped
  // Vehicles seen still long enough are parked (dynamic/parked_boxes.hpp): judged by geometry
  // alone, mapped and given to the object database like any static object. Off: every
  // dynamic-class box is a mover's.
  bool park_vehicles = true;
  std::vector<std::string> parkable_classes;  // empty: detect::default_parkable_classes()
  dynamic::ParkedBoxOptions parked;
  // A mover's box is carried across the frames its detection misses (detect/box_coasting.hpp):
  // predicted from its image velocity for up to box_coasting.max_frames frames.
  detect::BoxCoastOptions box_coasting;
  // The feature extractor may set the previous frame's mover boxes (grown by this margin, in
  // pixels, kMoverBudgetMarginPx when on) apart: the scenery gets the whole feature budget of
  // its own, and the movers keep the share they had (tracking::FeatureExtractor::extract).
  // Negative: off, one budget for the whole image. Off by default since the silhouettes below
  // keep the movers' corners out of the budget anyway; the split then only reshuffles the
  // scenery's corners around each walker as the boxes move (README, "Dynamic features").
  int mover_budget_margin_px = -1;
  // The extractor also leaves out the previous frame's movers themselves, pixel by pixel: the
  // depth readings of each mover box's object, grown (dynamic/mover_silhouette.hpp, which says
  // why; figures in the README, "Dynamic features"). Off: they compete with the scenery for the
  // budget as before.
  bool mover_silhouettes = true;
  dynamic::MoverSilhouetteOptions mover_silhouette;
  // World frame: the body pose this returns for the first frame's stamp (e.g. the ground
  // truth's, so maps and objects compare with a simulated world); when it is unset or returns
  // nothing, gravity-aligned from the IMU, else the first camera pose.
  std::function<std::optional<SE3>(Timestamp)> initial_T_w_body;
  // Place-recognition vocabulary (kestrel vocab); empty or missing: no loop closing.
  std::string vocabulary = std::string(KESTREL_SOURCE_DIR) + "/config/vocabulary.kvoc";
  // A verified loop enters the pose graph only when it agrees with the odometry within the
  // drift the path since the matched keyframe allows (loop/loop_gate.hpp); counted as
  // loop.rejected otherwise.
  loop::LoopGateOptions loop_gate;
  // How far the pose graph trusts the odometry between keyframes and each loop
  // (loop/edge_sigmas.hpp; checked when the System is built). Eighteen lock-step 60 s draws
  // with loops, one sigma pair for every edge -> these with a loop at 1 cm: APE summed 0.612 ->
  // 0.562 m; the loop's 3 cm came with the least-similar rule (README "Loop closing").
  loop::EdgeSigmas pose_graph_sigmas;
  std::string load_map;  // map.bin of an earlier session: relocalize in it (multi-session)
  // RGB-D + IMU / stereo + IMU: the IMU predicts each frame's pose for the tracker and carries
  // the pose through a lost track (when the calibration has an IMU). Off: visual only.
  bool use_imu = true;
  // Local BA on its own thread (the tracker's inline_mapping off); false: inside track().
  bool async_local_ba = true;
  imu::InertialPredictorOptions inertial;  // noise is taken from the calibration
  // The IMU's prediction also weighs in each frame's pose optimization (a PosePrior with
  // these sigmas one frame after a fix), and vision that disagrees with it is re-matched
  // around it (TrackerOptions::prior_gate_chi2). Off by default because it cost accuracy:
  // office-static (24 s) 1.28 -> 1.97 cm, and with the sigmas loosened to 2 cm / 5 mrad
  // uav-zigzag (no movers) 0.24 -> 0.44 m; with the gate the drone lost track for seconds.
  // The prediction inherits the fixes' errors through the velocity fit, so vision and IMU
  // are not independent here; that needs a sliding-window visual-inertial estimate.
  bool inertial_prior = false;
  // With inertial_prior off, the prediction still gates vision: a pose further from it than
  // this chi-square (in the prediction's tight sigmas) is re-matched around the prediction,
  // and dropped (the IMU carries the frame) if it still disagrees. Walkers filling the view
  // pulled a 20-inlier pose 0.2 m and 2.4 degrees off in one frame (market at 17.7 s, chi2
  // 2450). When this was set (2000), honest frames reached a few hundred and at 400
  // uav-zigzag's turns lost 30 frames; with the gyro rotation prior and the IMU-checked flow
  // since, their chi-square stays under 10 on uav-zigzag without movers, p99.9 under 60 on
  // market, cafe and corridor-dark (frames.csv, 60 s). A car filling the drone's view
  // (uav-zigzag at 3.5 s) came at 629, passed, and its motion then became the IMU's through
  // the fixes (3.5 m off by 4 s). At 150, with the depth carry's and the dynamic filter's
  // checks (depth_carry_max_correction_chi2, DynamicFilterOptions::prior_without_support) and
  // FAST at 20 (FeatureExtractorOptions), 60 s APE over three draws (kestrel sim --seed 1/2/3):
  // uav-zigzag 1.52 / 0.32 / 0.44 -> 0.38 / 0.097 / 0.117 m; market (1, 2) 0.060 / 0.073 ->
  // 0.047 / 0.047; cafe (1, 3) 0.010 / 0.006 -> 0.014 / 0.005; corridor-dark (1, 2)
  // 0.28 / 0.095 -> 0.23 / 0.066. 0: no gate. Tighter is worse: at 60, where uav-zigzag's cars
  // pulled vision 4-8 cm per step off the truth at chi-square 20-118, APE went 0.065 -> 0.070 and
  // 0.099 -> 0.121 m (seeds 1 and 4), market seeds 2 and 3 unchanged.
  double inertial_gate_chi2 = 150.0;
  // Keyframes carry the gyro's rotation since the keyframe before them and local BA holds
  // them to it (mapping::GyroLink): without, a map tilts wherever vision's errors lead it
  // (market, no movers: 6 degrees in 8 s). The link's sigma adds to the gyro's white noise and
  // bias uncertainty a floor and a share of the angle turned (camera-IMU rotation error).
  bool gyro_links = true;
  double gyro_link_sigma_floor = 1e-4;      // radians
  double gyro_link_relative_sigma = 0.005;  // of the angle turned
  // Where gravity is learnt from the first tracked frames (a world that is the first camera's:
  // EuRoC, whose IMU starts with its first image), the gyro's mean over a still stretch of the
  // last second then, if there is one (imu::static_initialize), is the gyro bias, with the
  // standard error of that mean as its sigma. Otherwise the bias starts at zero and is learnt
  // from vision over 2 s windows, while the prediction already turns with it: EuRoC V1_01's gyro
  // reads 0.08 rad/s about z at rest, and stereo + IMU on V1_01_micro scored APE 42 mm with it
  // left at zero, 7.2 mm with it, 1.0 mm once the gyro prior also counted the bias's
  // uncertainty until it is measured (stereo alone 0.9 mm).
  // Worlds aligned at the first frame (ground truth, or an IMU that started before it) never
  // take this path.
  bool static_gyro_bias = true;
  // Keyframes also carry the IMU's whole pre-integration since the keyframe before them and
  // its velocity, and local BA is visual-inertial (imu::solve_inertial_local_ba): the
  // accelerometer holds how far and how fast the body moved between keyframes. Off by default:
  // over three draws of each world (kestrel sim --seed, 60 s, APE in metres, off -> on) it won
  // on uav-zigzag (0.543 0.469 0.501 -> 0.512 0.386 0.222) but lost on the medians of cafe
  // (0.010 0.106 0.485 -> 0.205 0.077 0.418) and market (0.180 0.748 0.259 -> 0.155 0.707
  // 0.382), and on corridor-dark (0.63 -> 1.41); office-static (24 s) 6.5 -> 7.0 mm. It places
  // keyframes that vision cannot (imu tests), but what these scenes lose is frames, not
  // keyframes: tracking's poses still come from vision and the predictor, not from this
  // estimate. Measured again on today's system (eleven 60 s draws, lost frames and APE m, off ->
  // on): cafe seeds 1-3 0.0048 / 0.0090 / 0.0050 -> 0.0043 / 0.0045 / 0.0030; market 1-3 0,
  // 0.049 / 21, 0.060 / 1, 0.035 -> 0, 0.060 / 19, 0.037 / 0, 0.038; uav-zigzag 1, 4, 5 0.066 /
  // 0.038 / 0.059 -> 0.048 / 0.073 / 0.074 (none lost); corridor-dark 1 and 3 0.062 / 0.051 ->
  // 0.074 / 0.067 (one lost each both ways): lost 24 -> 21, APE summed 0.44 -> 0.48 m, better on
  // five draws (every cafe draw), worse on six. Still off.
  bool inertial_ba = false;
  // The dynamic filter checks its ego-motion against the IMU's predicted camera motion
  // (dynamic::DynamicFilterInput::t_cur_prev).
  bool dynamic_motion_prior = true;
  // A relocalization during a short loss restarts the IMU predictor from the relocalized pose
  // with the IMU's velocity (imu::InertialPredictor::reanchor); false: it waits for new fixes.
  bool reanchor_on_relocalization = true;
  // ... but only with a velocity last fitted to vision fixes at most this long ago: through a
  // flaky stretch (lost, relocalized, lost again) a velocity handed from reanchor to reanchor
  // is the IMU's own integration, never checked again. 2 s let uav-zigzag (seed 2) drift 47 m
  // away; 0.5 s keeps the 3.7 s relocalization under a walker of the default seed.
  double reanchor_velocity_max_age_s = 0.5;
  // Each frame's pose optimization holds its rotation near the previous frame's tracked one
  // turned by the gyro since then (tracking::Tracker::set_rotation_prior), with the gyro's
  // white noise over the interval plus a floor and a share of the angle turned (camera-IMU
  // rotation error). Only rotation: the gyro's relative rotation is nearly drift-free over a
  // frame and owes nothing to vision, unlike the predicted translation (inertial_prior).
  // Walkers' features that slip past the dynamic filter pulled vision's yaw the same way frame
  // after frame (cafe seed 4: 0.01-0.07 rad/s against the gyro's < 0.001, 42 degrees in 60 s;
  // without movers the same world tracks to 4 mm). Over three draws of each world (kestrel sim
  // --seed, 60 s, APE in metres, off -> on): uav-zigzag 0.543 0.469 0.501 -> 0.534 0.066 0.220,
  // cafe 0.010 0.106 0.485 -> 0.015 0.011 0.087, market 0.180 0.748 0.259 -> 0.134 0.181 0.126.
  // A floor of 5e-5 rad (4x tighter) lost on cafe (0.054 0.348 0.295). corridor-dark (no
  // movers, --dynamic off): 129 -> 83 lost frames but 0.63 -> 1.41 m; its attitude holds (3
  // against 12 degrees off at 18 s) while the noise features of its dark walls push the free
  // translation instead (27 cm upwards between 12 and 15 s). office-static 24 s: 6.5 -> 7.8 mm.
  bool gyro_rotation_prior = true;
  double gyro_prior_sigma_floor = 2e-4;             // radians
  double gyro_prior_relative_sigma = 0.005;         // of the angle turned
  double inertial_prior_rotation_sigma = 0.001;     // radians
  double inertial_prior_translation_sigma = 0.005;  // metres
  // A frame that features cannot track (a bare wall filling the view) while the IMU predicts
  // its motion is aligned by its depth to the frame before (tracking::align_depth), the gyro's
  // rotation and the IMU's translation as the prior: depth fixes the distance to what it sees,
  // the IMU the rest. The pose is a fix for the IMU predictor, so its velocity and its gate
  // against relocalizations stay fresh; for at most depth_carry_max_s after vision's last fix.
  // 60 s runs (kestrel run, APE; --no-depth-carry -> on): corridor-dark 1.59 -> 0.28 m and,
  // drawn with --seed 2, 0.36 -> 0.095 m (its turn facing the bare end wall: 64 frames aligned;
  // before, false relocalizations there moved it 0.3-0.9 m); market 0.060 -> 0.060 (movers fill
  // the view when it loses features: left to the IMU, DepthAlignmentOptions::max_excluded_share);
  // cafe 0.010 and ugv-loop 0.015 (never lost); uav-zigzag 1.53 -> 1.52 and seed 2 0.27 -> 0.32
  // (a scene whose draws span 0.3-1.7 m; the default draw goes wrong at 4 s, cars outvoting the
  // ground, before either acts). Without the IMU check below, uav-zigzag with --half-res-flow
  // went 0.90 -> 13.6 m; with it 4.9 m, a draw already 2.7 m off at 4 s.
  bool depth_carry = true;
  double depth_carry_max_s = 3.0;
  double depth_carry_translation_sigma = 0.01;  // metres: the IMU's motion over one frame
  // ... and only when vision agreed with the IMU before the loss: the median chi-square of the
  // IMU prediction against the last 10 tracked frames (6 dof; 16.8 is the 99% point).
  double depth_carry_max_imu_chi2 = 16.8;
  // ... and an alignment that moves the IMU's motion further than this chi-square (in the
  // prior's sigmas, 6 dof) is refused: depth then aligned to a mover filling the view, not to
  // the world (uav-zigzag at 3.5 s, a car under the drone that the detector misses: 300-340,
  // and its fixes turned the IMU's velocity into the car's). corridor-dark's honest
  // corrections stay under 0.4.
  double depth_carry_max_correction_chi2 = 9.0;
  tracking::DepthAlignmentOptions depth_alignment;
  // Corners followed from the frame before (tracking::follow_corners) weigh in beside the
  // depth. When the two fix the step in every direction (a bare wall's blotches along it, its
  // depth across it) to frame_to_frame_min_information, the frame is tracked frame to frame,
  // not lost: DepthAlignmentResult::weakest_information, 2.5e5 is 2 mm or 2 mrad in the
  // weakest direction, against a median 4 mm step error of the frames corridor-dark tracks
  // against its map. On its bare end wall (seed 6, 17.9-20.3 s) the tracked steps came to
  // 0.1-1.5 mm of the truth, with 5.7e5-1.1e6.
  bool corner_tracks = true;
  tracking::CornerTrackOptions corner_track_options;
  double frame_to_frame_min_information = 2.5e5;
  // After a frame tracked frame to frame, a lost track keeps looking for its map instead of
  // bridging to a new one (TrackerOptions::bridge_after_lost_frames, Tracker::set_hold_bridge):
  // a bridge's map starts at the IMU's pose, and the frames then tracked on the few ORB points
  // it seeds on a bare wall step 4 mm off where frame to frame steps 0.5, while the old map,
  // found again after the wall, keeps the path joined to where it was. Nine 40 s draws of
  // corridor-dark (APE m, off -> on): 0.070 / 0.218 / 0.084 / 0.112 / 0.095 / 0.060 / 0.100 /
  // 0.101 / 0.073 -> 0.080 / 0.107 / 0.056 / 0.087 / 0.068 / 0.059 / 0.085 / 0.072 / 0.071
  // (sum 0.91 -> 0.68, better on eight), lost frames 23 -> 31 in all.
  bool frame_to_frame_holds_bridge = true;
  // ... but only for a frame that alignment does track: during such a stretch the frame is
  // aligned before the tracker runs, and one that neither its map nor alignment tracks bridges
  // at once instead of a frame later. That frame was lost on every corridor-dark draw: the
  // corner at the end of the bare wall comes into view, its new corners have no tracks from the
  // frame before (the weakest direction 3.5e4 where 2.5e5 is asked), and the next frame's bridge
  // seeded 725 points. Nine 40 s draws (lost frames, APE m), off -> on: 1, 0.062 / 1, 0.118 /
  // 1, 0.051 / 2, 0.123 / 2, 0.066 / 1, 0.086 / 1, 0.088 / 1, 0.089 / 1, 0.058 -> 0, 0.084 /
  // 0, 0.160 / 0, 0.052 / 0, 0.084 / 0, 0.066 / 0, 0.062 / 0, 0.093 / 0, 0.072 / 0, 0.067:
  // lost 11 -> 0, APE summed 0.741 -> 0.742 (better on three draws, worse on four; the bridge
  // a frame earlier changes which keyframes follow, and the draws part from 24 s on).
  // The bridged frame's pose is still the IMU's (SystemOptions::frame_to_frame_holds_bridge):
  // starting the bridge at the depth-aligned pose instead changed no draw by over 2 mm.
  bool bridge_where_alignment_fails = true;
  // ... and vision that finds the map again right after such a frame must agree with the IMU's
  // prediction to this chi-square (6 dof, 99%) instead of inertial_gate_chi2: the prediction
  // rests on the frame-to-frame fixes, and the wall's 26-37 inlier re-acquisitions at 50-70
  // were half a degree off (the next frame then IMU-carried or pulled between). Nine draws of
  // corridor-dark (APE m, 150 -> 16.8): seed 1 0.080 -> 0.072, 4 0.087 -> 0.074, 8 0.072 ->
  // 0.089, 9 0.071 -> 0.058, five unchanged (sum 0.683 -> 0.666); lost 31 -> 23, none carried
  // by the IMU alone (3 before). 0: inertial_gate_chi2 there too.
  double frame_to_frame_gate_chi2 = 16.8;
  // The mapping, bundle-adjustment and loop-closing threads run this many nice steps below
  // tracking and detection (0: the same): on two cores the three of them compete with the two
  // per-frame threads, and a frame's pose waited behind a local BA.
  int background_nice = 10;
  // The dense maps (cloud, OctoMap, grid) take a keyframe at most this often (stream seconds;
  // the object database takes every one). 0: every keyframe. Keyframes come 6-11 a second on
  // market and uav-zigzag with nearly the same view, and since the maps trust a drone's depth
  // to its sensor's 13 m (maps::map_builder_options) one insertion costs the mapping thread
  // about 150 ms there: the tracking thread waited on its queue and a live run of uav-zigzag
  // (seed 1, --realtime) dropped 522-543 of 1501 frames (216 with the old 8 m), frame to pose
  // p99 222-246 ms. With 0.25 s: 22-48 dropped, p99 45-67 ms; APE 0.054 / 0.104 m against
  // 0.031 / 0.034 with the drops (lock-step, every frame: 0.072). Live market seed 1: 0 dropped
  // either way, p99 27 -> 24 ms. The maps are scored at 3 keyframes a second (kestrel bench
  // --only objects). Since the batch OctoMap update (maps/octree_batch_update) an insertion costs
  // 43-67 ms there (p50, live); live uav-zigzag seed 1 every keyframe: 0 / 3 dropped, p99 37 /
  // 49 ms; with 0.25 s: 0 / 1 dropped, p99 29 / 32 ms.
  double dense_map_interval_s = 0.25;
  // Live (not sequential) runs wait at most this long for the IMU to pass a frame's stamp.
  double imu_wait_ms = 20.0;
};

// Where a frame's pose came from.
enum class PoseSource {
  kNone,       // not tracked yet (initializing) or lost without an IMU: the last good pose
  kVision,     // tracked against the map
  kVisionImu,  // tracked, after vision first disagreed with the IMU and was re-matched
  kBridged,    // lost, restarted the local map at the IMU's pose
  kImu,        // lost, the IMU's dead reckoning
  kDepthImu,   // lost to features, the IMU's motion corrected by aligning depth to the last frame
  // lost to the map, tracked from the last frame: depth and corners followed from it fixed the
  // step in all six directions (DepthAlignmentResult::weakest_information)
  kFrameToFrame,
};
const char* to_string(PoseSource s);

// The IMU prediction's uncertainty, as the tracker's prior and the dynamic filter take it
// (tracking::MotionPrior sigmas): the gyro is good to a few hundredths of a degree per frame;
// what the prior must allow for is the previous fix's own error and, in translation, the
// velocity's, both growing with the time the IMU carried the pose alone (since_fix_s).
struct InertialPriorSigmas {
  double rotation_rad = 0.0;
  double translation_m = 0.0;
};
InertialPriorSigmas inertial_prior_sigmas(const SystemOptions& options, double since_fix_s);
// How long the IMU has carried the pose as far as the prior's sigmas go: since the last fix, or
// since a bridge when one came later (since_bridge_s; negative: none). A bridge restarts the
// local map at the IMU's own pose, so the next frames' vision against that map can only be off
// the IMU by what the IMU drifted since the bridge. Counted from the fix instead, a pose on a
// map the bridge seeded from a passing car (uav-zigzag's take-off, seed 1, 3.73 s: a 0.19 m
// step against a true 0.07) passed the gate at chi-square 12.2 with a 5.4 cm sigma, and the
// IMU's velocity took its error on; counted from the bridge (7 mm) it is rejected, and the
// filter, with the tighter prior, no longer takes the car's motion for the camera's (670 of
// the frame's features flagged instead of 53). 60 s runs (lost frames, APE m): uav-zigzag
// seed 3 20, 0.114 -> 19, 0.065; seed 1 14, 0.105 -> 14, 0.171 (its position error at 4.8 s
// 0.22 -> 0.06 m, but the one loop the old run closed near landing was not found, so drift
// stayed); seed 2, corridor-dark (frequent bridges) x3 and market seed 2 unchanged.
double inertial_prior_age(double since_fix_s, double since_bridge_s);

// What observers get for every frame (DSO's Output3DWrapper seam: writers, telemetry, report).
struct FrameReport {
  Timestamp t = 0;
  SE3 T_w_body;
  tracking::TrackingState state = tracking::TrackingState::kInitializing;
  bool inertial_only = false;  // lost, and T_w_body is the IMU's dead reckoning
  PoseSource source = PoseSource::kNone;
  double imu_chi2 = -1.0;  // vision's disagreement with the IMU's prediction; -1: none made
  int features = 0;
  int dynamic_features = 0;
  int inliers = 0;
  int local_points = 0;    // the local map tracking matched against (TrackResult)
  int visible_points = 0;  // of those, in view at the final (lost: predicted) pose
  int detections = 0;      // dynamic-class boxes matched to this frame, carried ones too
  bool keyframe = false;
  double latency_ms = 0.0;         // frame arrival to pose
  dynamic::RemovalCounts removal;  // against the truth mask, when one is provided
  // What the filter decided, for debug images and the report's frame strip.
  std::vector<Vec2> feature_px;
  std::vector<std::uint8_t> feature_dynamic;  // 1 = rejected as dynamic
  std::vector<dynamic::BoxRegion> boxes;      // ... and their regions (BoxCoaster's included)

  // What the camera saw did not fix the pose: the map lost it and it was not tracked frame to
  // frame either (System::frames_lost counts these).
  bool lost() const {
    return state == tracking::TrackingState::kLost && source != PoseSource::kFrameToFrame;
  }
};

// The object database after a change (DESIGN.md: observers receive map updates): every object
// it reports (ObjectDatabase::objects, world frame), after each keyframe the mapping thread
// folded in and once more after finish() when loop closure moved keyframes.
struct ObjectsReport {
  Timestamp t = 0;                // stamp of the keyframe that caused the update
  std::int64_t keyframe_id = -1;  // -1: the end-of-run loop correction
  std::vector<semantic::SemanticObject> objects;
};

class Observer {
 public:
  virtual ~Observer() = default;
  virtual void on_frame(const FrameReport& report) = 0;
  // Called on the mapping thread (and, for the final report, the thread calling finish()); the
  // default ignores it so frame-only observers need not care.
  virtual void on_objects(const ObjectsReport& /*report*/) {}
};

// Ground-truth mover mask of the frame at t (16-bit ids), or an empty Image.
using TruthMaskProvider = std::function<Image(Timestamp)>;

class System {
 public:
  // detector may be null (no detection: --detector none).
  System(const Calibration& calib, SystemOptions options,
         std::unique_ptr<detect::Detector> detector);
  ~System();
  System(const System&) = delete;
  System& operator=(const System&) = delete;

  void add_observer(Observer* observer);
  void set_truth_masks(TruthMaskProvider provider);
  // Frames are queued (back-pressure when tracking falls behind); IMU samples are buffered.
  void feed(const Measurement& m);
  // Drains the queues and joins the threads. Called by the destructor too.
  void finish();

  Trajectory trajectory() const;  // T_w_body of every tracked frame
  // keyframes.txt (TUM, T_w_body), map.bin, sparse.ply, and the dense maps (cloud.ply,
  // octomap.bt, map.pgm + map.yaml) and objects.json, after finish().
  void write_map_outputs(const std::string& dir) const;
  dynamic::RemovalCounts removal() const;
  const StageStats& stats() const;
  // Frames whose pose what the camera saw did not fix: lost to the map and not tracked frame to
  // frame (PoseSource::kFrameToFrame) either; the IMU or depth with the IMU carried them, or
  // none.
  std::size_t frames_lost() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::pipeline
