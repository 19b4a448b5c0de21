#include "comm/agent_runner.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "comm/grid_delta.hpp"
#include "comm/object_telemetry.hpp"
#include "comm/telemetry_observer.hpp"
#include "comm/webrtc_link.hpp"
#include "core/error.hpp"
#include "detect/oracle_detector.hpp"
#include "detect/yolo_fastest.hpp"
#include "io/trajectory_io.hpp"
#include "maps/grid_io.hpp"
#include "maps/map_builder.hpp"
#include "nav/astar_planner.hpp"
#include "pipeline/live_feed.hpp"
#include "pipeline/system.hpp"

namespace kestrel::comm {
namespace {

// Collects keyframe poses from the tracking thread for the main loop's map builder.
class KeyframeCollector : public pipeline::Observer {
 public:
  void on_frame(const pipeline::FrameReport& r) override {
    std::lock_guard lock(mutex_);
    if (r.state == tracking::TrackingState::kOk ||
        r.state == tracking::TrackingState::kRelocalized) {
      last_pose_ = r.T_w_body;
      if (!have_first_) {
        first_pose_ = r.T_w_body;
        have_first_ = true;
      }
      if (r.keyframe) keyframes_.emplace_back(r.t, r.T_w_body);
    }
  }
  std::vector<std::pair<Timestamp, SE3>> take() {
    std::lock_guard lock(mutex_);
    std::vector<std::pair<Timestamp, SE3>> out(keyframes_.begin(), keyframes_.end());
    keyframes_.clear();
    return out;
  }
  bool poses(SE3& first, SE3& last) const {
    std::lock_guard lock(mutex_);
    first = first_pose_;
    last = last_pose_;
    return have_first_;
  }

 private:
  mutable std::mutex mutex_;
  std::deque<std::pair<Timestamp, SE3>> keyframes_;
  SE3 first_pose_, last_pose_;
  bool have_first_ = false;
};

// The tracker's view of the latest frame, for viewers that asked for an overlay. It lags the
// frame being sent by the tracking latency; waiting for it would add that latency to the video.
class OverlayCollector : public pipeline::Observer {
 public:
  void on_frame(const pipeline::FrameReport& r) override {
    VideoOverlay o;
    o.state = tracking::to_string(r.state);
    for (const auto& b : r.boxes) o.boxes.push_back({b.x_min, b.y_min, b.x_max, b.y_max});
    o.features.reserve(r.feature_px.size());
    for (std::size_t i = 0; i < r.feature_px.size(); ++i) {
      o.features.push_back({static_cast<float>(r.feature_px[i].x()),
                            static_cast<float>(r.feature_px[i].y()),
                            i < r.feature_dynamic.size() && r.feature_dynamic[i] != 0});
    }
    std::lock_guard lock(mutex_);
    last_ = std::move(o);
  }
  VideoOverlay latest() const {
    std::lock_guard lock(mutex_);
    return last_;
  }

 private:
  mutable std::mutex mutex_;
  VideoOverlay last_;
};

GridState to_state(const maps::OccupancyGrid& g, std::uint32_t seq) {
  GridState s;
  s.seq = seq;
  s.width = static_cast<std::uint32_t>(g.width());
  s.height = static_cast<std::uint32_t>(g.height());
  s.resolution = g.resolution();
  s.origin = {g.origin().x(), g.origin().y()};
  s.cells.reserve(g.cells().size());
  for (std::int8_t v : g.cells()) s.cells.push_back(v < 0 ? 255 : static_cast<std::uint8_t>(v));
  return s;
}

std::unique_ptr<detect::Detector> make_detector(const AgentRunOptions& o) {
  if (o.detector == "yolo") {
    return std::make_unique<detect::YoloFastest>(
        o.models_dir.empty() ? detect::find_models_dir() : o.models_dir,
        detect::pipeline_yolo_options(o.yolo_model));
  }
  if (o.detector == "oracle") {
    if (o.dataset_dir.empty()) throw Error("--detector oracle needs a sim: or kestrel: source");
    return std::make_unique<detect::OracleDetector>(io::read_boxes(o.dataset_dir + "/boxes.csv"));
  }
  if (o.detector != "none") {
    throw Error("unknown detector '" + o.detector + "' (yolo, oracle or none)");
  }
  return nullptr;
}

// Commands and pings are answered by the link's own thread; this keeps the status fresh (the
// station's liveness) and the viewers' picture moving at the encoder's rate.
void linger(const AgentRunOptions& options, TelemetryObserver& telemetry, WebRtcVideoLink* video,
            OverlayCollector& overlay, const Image& last_color) {
  if (options.linger_s <= 0) return;
  using clock = std::chrono::steady_clock;
  const auto end = clock::now() + std::chrono::duration_cast<clock::duration>(
                                      std::chrono::duration<double>(options.linger_s));
  const auto frame_period = std::chrono::duration_cast<clock::duration>(
      std::chrono::duration<double>(1.0 / (options.video ? options.video->fps : 1.0)));
  auto next_status = clock::now() + std::chrono::seconds(1);
  auto next_frame = clock::now();
  if (options.progress) {
    std::printf("  source finished; staying online for %.0f s\n", options.linger_s);
    std::fflush(stdout);
  }
  while (clock::now() < end) {
    const auto now = clock::now();
    if (now >= next_status) {
      telemetry.publish_status("finished");
      next_status = now + std::chrono::seconds(1);
    }
    if (video && !last_color.empty() && now >= next_frame) {
      const VideoOverlay o = overlay.latest();
      video->sender().push_frame(last_color, wall_clock_ns(), &o);
      next_frame += frame_period;
      if (next_frame < now) next_frame = now;
    }
    std::this_thread::sleep_until(std::min({end, next_status, video ? next_frame : end}));
  }
}

}  // namespace

AgentRunSummary run_agent(io::MeasurementSource& source, const AgentRunOptions& options) {
  const Calibration calib = source.calibration();
  pipeline::SystemOptions sys_opt;
  sys_opt.sequential = !options.realtime;
  // The agent's world is its own: its start position, z up, x along its start heading; never
  // the ground truth's, since a team's agents share no frame until mapd brings them into one.
  // With ground truth (a simulated or recorded run) its roll and pitch serve as an ideal
  // inclinometer: the pipeline's own fallback, 200 ms of accelerometer before the first
  // frame, has no samples at a source's very start and is tilted by motion at a later one.
  if (auto gt = source.ground_truth(); gt && !gt->empty()) {
    sys_opt.initial_T_w_body = [gt = std::move(*gt)](Timestamp t) -> std::optional<SE3> {
      const double ts = to_seconds(t);
      const auto it = std::lower_bound(gt.stamps.begin(), gt.stamps.end(), ts - 0.02);
      if (it == gt.stamps.end() || std::fabs(*it - ts) > 0.02) return std::nullopt;
      const Mat3 R = gt.poses[static_cast<std::size_t>(it - gt.stamps.begin())].rotation();
      const double yaw = std::atan2(R(1, 0), R(0, 0));
      const Mat3 level = Eigen::AngleAxisd(-yaw, Vec3::UnitZ()).toRotationMatrix() * R;
      return SE3(Quat(level), Vec3::Zero());
    };
  }
  pipeline::System system(calib, sys_opt, make_detector(options));
  KeyframeCollector keyframes;
  std::atomic<bool> paused{false};
  std::mutex map_mutex;  // guards grid and builder outputs used by the command handler
  maps::OccupancyGrid grid;
  std::atomic<std::uint64_t> paths{0};
  AgentLink* link_ptr = nullptr;

  auto plan_to = [&](const CommandMsg& c, const Vec2& goal) -> AckMsg {
    SE3 first, last;
    if (!keyframes.poses(first, last)) return {c.id, 0, AckResult::kRejected, "not tracking yet"};
    const Vec2 start(last.translation().x(), last.translation().y());
    nav::PlanResult plan;
    {
      std::lock_guard lock(map_mutex);
      if (grid.empty()) return {c.id, 0, AckResult::kRejected, "no occupancy grid yet"};
      nav::PlannerOptions po;
      po.robot_radius = options.robot_radius;
      // The camera looks ahead and never sees the floor under the robot, so the cells it stands
      // on may still be unknown; the robot being there proves them free (footprint clearing,
      // which the grid has for the keyframes: this is the latest pose), occupied ones too (a
      // station's goal was once refused with "start is inside an obstacle": the pose a few cm
      // into a desk's cells). Nor may the map reach back to where the robot stands: the grid
      // grows, unknown, to hold the robot's disc.
      const double res = grid.resolution();
      const double disc = (std::ceil(options.robot_radius / res) + 1.0) * res;
      const maps::OccupancyGrid g =
          maps::clear_footprints(grid, {{start, disc}}, res, /*over_obstacles=*/true);
      plan = nav::plan_path(g, start, goal, po);
    }
    if (!plan.ok()) return {c.id, 0, AckResult::kRejected, plan.message};
    PathMsg path;
    path.t = wall_clock_ns();
    path.goal_id = c.id;
    for (const Vec2& w : plan.waypoints) path.points.push_back({w.x(), w.y()});
    link_ptr->publish(path);
    ++paths;
    char detail[96];
    std::snprintf(detail, sizeof(detail), "path of %zu waypoints, %.2f m", plan.waypoints.size(),
                  plan.length);
    return {c.id, 0, AckResult::kDone, detail};
  };

  auto handle = [&](const CommandMsg& c) -> AckMsg {
    switch (c.kind) {
      case CommandKind::kPause:
        paused = true;
        return {c.id, 0, AckResult::kDone, "paused"};
      case CommandKind::kResume:
        paused = false;
        return {c.id, 0, AckResult::kDone, "resumed"};
      case CommandKind::kGoal:
        return plan_to(c, Vec2(c.goal[0], c.goal[1]));
      case CommandKind::kReturnHome: {
        SE3 first, last;
        if (!keyframes.poses(first, last)) return {c.id, 0, AckResult::kRejected, "no home yet"};
        return plan_to(c, Vec2(first.translation().x(), first.translation().y()));
      }
      case CommandKind::kSaveMap: {
        if (c.path.empty()) return {c.id, 0, AckResult::kRejected, "no path given"};
        try {
          std::filesystem::create_directories(c.path);
          io::write_tum(c.path + "/trajectory.txt", system.trajectory());
          std::lock_guard lock(map_mutex);
          if (!grid.empty()) maps::write_map(c.path + "/map.yaml", grid);
        } catch (const std::exception& e) {
          return {c.id, 0, AckResult::kRejected, e.what()};
        }
        return {c.id, 0, AckResult::kDone, "saved to " + c.path};
      }
      case CommandKind::kTeleop:
        return {c.id, 0, AckResult::kRejected, "a replayed source cannot be steered"};
    }
    return {c.id, 0, AckResult::kRejected, "unknown command"};
  };

  AgentLink link(options.link, handle);
  link_ptr = &link;
  TelemetryOptions telemetry_options;
  telemetry_options.pose.max_wait_ns =
      options.realtime ? static_cast<std::int64_t>(options.pose_wait_s * 1e9)
                       : std::numeric_limits<std::int64_t>::max();  // lock-step: always tracked
  TelemetryObserver telemetry(link, telemetry_options);
  system.add_observer(&telemetry);
  ObjectTelemetry objects(link);
  system.add_observer(&objects);
  system.add_observer(&keyframes);
  OverlayCollector overlay;
  std::unique_ptr<WebRtcVideoLink> video;
  if (options.video) {
    try {
      video = std::make_unique<WebRtcVideoLink>(options.link, *options.video);
      system.add_observer(&overlay);
      video->start();
    } catch (const std::exception& e) {
      // Telemetry and commands matter more than pictures: run on without video, loudly.
      std::fprintf(stderr, "kestrel agent: video off: %s\n", e.what());
    }
  }
  link.start();
  if (!link.wait_connected(std::chrono::seconds(10))) {
    std::fprintf(stderr,
                 "kestrel agent: broker not reachable yet; telemetry is dropped until it is\n");
  }
  telemetry.publish_status();

  maps::MapBuilder builder(maps::map_builder_options(calib.depth_max));
  std::deque<RgbdFrame> recent;  // depth of the last frames, for the keyframes tracked from them
  GridState published;
  std::uint32_t grid_seq = 0;
  AgentRunSummary summary;
  auto last_grid = std::chrono::steady_clock::now();
  bool new_keyframes = false;
  std::optional<Timestamp> last_mapped;  // the dense maps' pace, as the System's

  auto update_map = [&] {
    for (const auto& [t, T_w_body] : keyframes.take()) {
      if (last_mapped && to_seconds(t - *last_mapped) < sys_opt.dense_map_interval_s) continue;
      for (const RgbdFrame& f : recent) {
        if (f.t != t || f.depth.empty()) continue;
        last_mapped = t;
        maps::MapKeyframe kf;
        kf.T_w_c = T_w_body * calib.T_body_camera;
        kf.color = &f.color;
        kf.depth = &f.depth;
        kf.depth_scale = f.depth_scale;
        kf.camera = calib.camera;
        // A ground robot's body stood where it was: its disc is free in the grid.
        if (options.link.role == "ugv")
          kf.footprint = maps::Footprint{T_w_body.translation().head<2>(), options.robot_radius};
        builder.insert(kf);
        new_keyframes = true;
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (!new_keyframes || now - last_grid < std::chrono::duration<double>(options.grid_period_s)) {
      return;
    }
    last_grid = now;
    new_keyframes = false;
    maps::OccupancyGrid g = builder.grid();
    if (g.empty()) return;
    GridState current = to_state(g, ++grid_seq);
    const bool key = options.grid_keyframe_every <= 1 ||
                     (grid_seq - 1) % static_cast<std::uint32_t>(options.grid_keyframe_every) == 0;
    GridDeltaMsg msg = make_grid_delta(key ? GridState{} : published, current, wall_clock_ns());
    summary.grid_bytes += encode(msg).size();
    ++summary.grid_messages;
    link.publish(msg);
    published = std::move(current);
    std::lock_guard lock(map_mutex);
    grid = std::move(g);
  };

  auto last_snapshot = std::chrono::steady_clock::now();
  std::uint64_t snapshots = 0;
  auto snapshot_objects = [&](bool force) {
    const auto now = std::chrono::steady_clock::now();
    if (!force && now - last_snapshot < std::chrono::duration<double>(options.objects_snapshot_s)) {
      return;
    }
    last_snapshot = now;
    if (objects.messages() == 0) return;  // nothing to say yet
    link.publish_objects_snapshot();
    ++snapshots;
  };

  const auto wall0 = std::chrono::steady_clock::now();
  Timestamp first = -1;  // the source's first stamp
  Timestamp t0 = -1;     // the first stamp fed
  const Timestamp limit =
      options.duration_s > 0 ? static_cast<Timestamp>(options.duration_s * 1e9) : -1;
  const Timestamp skip = static_cast<Timestamp>(options.start_s * 1e9);
  // IMU samples from just before a late start still go in: the world frame is gravity-aligned
  // from the accelerometer over the 200 ms before the first frame.
  constexpr Timestamp kImuLead = 300'000'000;
  auto next_paused_status = std::chrono::steady_clock::now();
  Timestamp paused_ns = 0;
  std::size_t fed_frames = 0;
  std::chrono::steady_clock::time_point first_frame_wall, last_frame_wall;
  Image last_color;  // what a lingering agent's viewers keep seeing
  while (auto m = source.next()) {
    telemetry.poses().poll(wall_clock_ns());
    const Timestamp t = stamp_of(*m);
    if (first < 0) first = t;
    if (t - first < skip) {
      if (std::holds_alternative<ImuSample>(*m) && t - first >= skip - kImuLead) system.feed(*m);
      continue;
    }
    if (t0 < 0) t0 = t;
    if (limit >= 0 && t - t0 > limit) break;
    while (paused) {
      const auto p0 = std::chrono::steady_clock::now();
      if (p0 >= next_paused_status) {
        telemetry.publish_status("paused");
        next_paused_status = p0 + std::chrono::seconds(1);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      telemetry.poses().poll(wall_clock_ns());
      paused_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(
                       std::chrono::steady_clock::now() - p0)
                       .count();
    }
    if (options.realtime) {
      const double rate = options.rate > 0.0 ? options.rate : 1.0;
      std::this_thread::sleep_until(
          wall0 + std::chrono::nanoseconds(
                      static_cast<std::int64_t>(static_cast<double>(t - t0) / rate) + paused_ns));
    }
    bool drop = false;
    if (!std::holds_alternative<ImuSample>(*m)) {
      telemetry.poses().on_camera_frame(t, wall_clock_ns());
      last_frame_wall = std::chrono::steady_clock::now();
      if (fed_frames + summary.frames_dropped == 0) first_frame_wall = last_frame_wall;
      // Not fed while the tracker is busy (its pose is predicted).
      drop = options.realtime && pipeline::drop_live_frame(fed_frames, telemetry.frames_reported(),
                                                           options.max_frames_in_flight);
      if (drop) {
        ++summary.frames_dropped;
        telemetry.set_drops(summary.frames_dropped);
      } else {
        ++fed_frames;
      }
    }
    if (const auto* f = std::get_if<RgbdFrame>(&*m)) {
      ++summary.frames;
      if (video) {
        const VideoOverlay o = overlay.latest();
        video->sender().push_frame(f->color, wall_clock_ns(), &o);
        last_color = f->color;
      }
      if (!drop) {
        recent.push_back(*f);
        if (recent.size() > 16) recent.pop_front();
      }
      if (options.progress && summary.frames % 100 == 0) {
        std::printf("  %zu frames, %llu poses published\n", summary.frames,
                    static_cast<unsigned long long>(telemetry.poses_published()));
        std::fflush(stdout);
      }
    }
    if (!drop) system.feed(*m);
    update_map();
    snapshot_objects(false);
  }
  system.finish();
  telemetry.poses().flush();
  new_keyframes = true;
  last_grid = {};
  update_map();
  snapshot_objects(true);
  telemetry.publish_status("finished");
  linger(options, telemetry, video.get(), overlay, last_color);
  // Let the outbox drain before the link says goodbye.
  for (int i = 0; i < 100 && link.client().outbox_size() > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  summary.tracked = system.trajectory().size();
  summary.poses_published = telemetry.poses_published();
  summary.poses = telemetry.poses().counts();
  const double replay_s = std::chrono::duration<double>(last_frame_wall - first_frame_wall).count();
  const std::size_t camera_frames = fed_frames + summary.frames_dropped;
  summary.camera_rate_hz = replay_s > 0 ? static_cast<double>(camera_frames - 1) / replay_s : 0.0;
  summary.paths_published = paths;
  summary.object_messages = objects.messages();
  summary.object_snapshots = snapshots;
  summary.objects = objects.objects();
  summary.link = link.counts();
  summary.mqtt = link.client().stats();
  if (video) {
    summary.video = video->sender().stats();
    summary.video_on = true;
  }
  summary.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return summary;
}

}  // namespace kestrel::comm
