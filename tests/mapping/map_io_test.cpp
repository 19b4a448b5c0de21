#include "mapping/map_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>

#include "core/error.hpp"
#include "io/trajectory_io.hpp"
#include "sim/scenario.hpp"
#include "sim/simulator.hpp"
#include "tests/test_paths.hpp"
#include "tracking/tracker.hpp"

namespace kestrel::mapping {
namespace {

RgbdFrame to_rgbd(const sim::SimFrame& f, const Calibration& calib) {
  RgbdFrame r;
  r.t = f.stamp;
  r.color = f.color;
  r.depth = f.depth;
  r.depth_scale = calib.depth_scale;
  return r;
}

// The first 3 s of office-static, tracked once and shared by the tests (rendering is the
// cost). Its hand-held loop ends where it started, so the end of the clip revisits the place
// the first session mapped.
class MapIo : public ::testing::Test {
 protected:
  static constexpr int kFirstSessionFrames = 90;
  static constexpr int kRevisitedFrame = 15;

  static void SetUpTestSuite() {
    sim_ = new sim::Simulator(sim::load_scenario("office-static"));
    tracker_ = new tracking::Tracker(sim_->calibration().camera);
    tracker_->set_initial_pose(sim_->camera_pose(sim_->frame_time(0)));
    for (int k = 0; k < kFirstSessionFrames; ++k) {
      const sim::SimFrame f = sim_->render(k);
      const tracking::TrackResult r = tracker_->track(to_rgbd(f, sim_->calibration()));
      ASSERT_EQ(r.state, tracking::TrackingState::kOk) << "first session, frame " << k;
      // The map must be good where the second session comes back, or 5 cm cannot hold.
      ASSERT_LT((r.T_w_c.translation() - sim_->camera_pose(f.time).translation()).norm(), 0.03)
          << "first session, frame " << k;
    }
  }
  static void TearDownTestSuite() {
    delete tracker_;
    delete sim_;
    tracker_ = nullptr;
    sim_ = nullptr;
  }
  static const Map& map() { return tracker_->map(); }
  static void relocalize_at_loop_end(const tracking::TrackerOptions& options);

  static sim::Simulator* sim_;
  static tracking::Tracker* tracker_;
};
sim::Simulator* MapIo::sim_ = nullptr;
tracking::Tracker* MapIo::tracker_ = nullptr;

std::string read_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void expect_error_naming(const std::string& bytes, const std::string& name, const char* what) {
  try {
    deserialize_map(bytes, name);
    ADD_FAILURE() << "no error for " << what;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}

TEST_F(MapIo, RoundTripKeepsEverything) {
  ASSERT_GT(map().num_keyframes(), 1u);
  ASSERT_GT(map().num_points(), 500u);
  const auto dir = test::temp_dir("map_io_round_trip");
  const std::string path = (dir / "map.bin").string();
  save_map(path, map());
  const Map loaded = load_map(path);
  std::cout << "map.bin: " << map().num_keyframes() << " keyframes, " << map().num_points()
            << " points, " << std::filesystem::file_size(path) / 1024 << " KiB\n";
  ASSERT_EQ(loaded.num_keyframes(), map().num_keyframes());
  ASSERT_EQ(loaded.num_points(), map().num_points());
  for (const auto& [id, kf] : map().keyframes()) {
    const Keyframe* other = loaded.keyframe(id);
    ASSERT_NE(other, nullptr);
    EXPECT_EQ(other->t, kf.t);
    EXPECT_LT((other->T_w_c.matrix() - kf.T_w_c.matrix()).norm(), 1e-12);
    EXPECT_EQ(other->point_of_feature, kf.point_of_feature);
    EXPECT_EQ(other->connections, kf.connections);
    ASSERT_EQ(other->features.size(), kf.features.size());
    for (std::size_t i = 0; i < kf.features.size(); ++i) {
      EXPECT_EQ(other->features.descriptors[i], kf.features.descriptors[i]);
      EXPECT_EQ(other->features.keypoints[i].px, kf.features.keypoints[i].px);
      EXPECT_EQ(other->features.depth[i], kf.features.depth[i]);
    }
    // The radius search works on the loaded features (grid rebuilt).
    const auto& k0 = other->features.keypoints.front();
    EXPECT_FALSE(other->features.in_radius(k0.un.x(), k0.un.y(), 1.0).empty());
  }
  for (const auto& [id, p] : map().points()) {
    const MapPoint* q = loaded.point(id);
    ASSERT_NE(q, nullptr);
    EXPECT_EQ(q->p_w, p.p_w);
    EXPECT_EQ(q->descriptor, p.descriptor);
    EXPECT_EQ(q->observations, p.observations);
    EXPECT_EQ(q->max_distance, p.max_distance);
  }
  // Equal maps, equal sizes (quaternions are re-normalized on load, so bits may move).
  EXPECT_EQ(serialize_map(loaded).size(), read_bytes(path).size());
  // The file is streamed in pieces (several here), yet holds exactly serialize_map's bytes,
  // and the temporary it was written to is gone.
  EXPECT_GT(std::filesystem::file_size(path), 3u << 18);  // three 256 KiB pieces and more
  EXPECT_TRUE(read_bytes(path) == serialize_map(map()));
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}

TEST_F(MapIo, FailedSaveKeepsThePreviousFile) {
  const auto dir = test::temp_dir("map_io_failed_save");
  const std::string path = (dir / "map.bin").string();
  save_map(path, map());
  const std::string before = read_bytes(path);
  // The temporary beside it cannot be created (a folder holds its name): the save fails with
  // an error naming it, and the map saved before is untouched.
  std::filesystem::create_directory(path + ".tmp");
  try {
    save_map(path, Map());
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("map.bin.tmp"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(read_bytes(path) == before);
  EXPECT_NO_THROW(load_map(path));
}

TEST_F(MapIo, NewIdsContinuePastTheLoadedOnes) {
  Map loaded = deserialize_map(serialize_map(map()), "mem");
  const KeyframeId kid = loaded.add_keyframe(0, SE3(), map().keyframes().begin()->second.features);
  EXPECT_EQ(kid, map().last_keyframe_id() + 1);
  const PointId pid = loaded.add_point(Vec3(1, 2, 3), kid, 0);
  EXPECT_EQ(map().point(pid), nullptr);
}

TEST_F(MapIo, BadFilesAreRejectedWithTheirNames) {
  const std::string good = serialize_map(map());
  std::string bad_magic = good;
  bad_magic[0] = 'X';
  expect_error_naming(bad_magic, "bad_magic.bin", "magic");
  std::string bad_version = good;
  const std::uint32_t v = kMapFormatVersion + 1;
  std::memcpy(bad_version.data() + 8, &v, sizeof(v));
  expect_error_naming(bad_version, "future.bin", "version");
  // Truncation anywhere: in the header, a keyframe, the points, the end marker.
  expect_error_naming(good.substr(0, 3), "short.bin", "magic");
  for (std::size_t cut : {std::size_t{10}, std::size_t{100}, good.size() / 3, good.size() / 2,
                          good.size() - 100, good.size() - 2}) {
    expect_error_naming(good.substr(0, cut), "cut.bin", "truncated");
  }
  expect_error_naming(good + "x", "long.bin", "unexpected bytes");
  // An image size that would size the feature grid in gigabytes is refused, not allocated.
  Map huge = deserialize_map(good, "mem");
  huge.keyframe(huge.keyframes().begin()->first)->features.width = 1 << 30;
  expect_error_naming(serialize_map(huge), "huge.bin", "keyframe.width");
  EXPECT_THROW(load_map("/nonexistent/map.bin"), Error);
  try {
    load_map("/nonexistent/map.bin");
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/map.bin"), std::string::npos);
  }
}

TEST_F(MapIo, BrokenLinksAreRejected) {
  // Points that claim features of a keyframe whose features no longer name them.
  Map copy = deserialize_map(serialize_map(map()), "mem");
  const KeyframeId kf = copy.points().begin()->second.observations.begin()->first;
  copy.keyframe(kf)->point_of_feature.assign(copy.keyframe(kf)->point_of_feature.size(), kNoPoint);
  expect_error_naming(serialize_map(copy), "links.bin", "does not link back");
}

TEST_F(MapIo, KeyframesAndPointsOutputs) {
  const auto dir = test::temp_dir("map_io_outputs");
  const SE3 T_body_camera = sim_->calibration().T_body_camera;
  write_keyframes_tum((dir / "keyframes.txt").string(), map(), T_body_camera);
  const Trajectory kfs = io::read_trajectory((dir / "keyframes.txt").string());
  ASSERT_EQ(kfs.size(), map().num_keyframes());
  std::size_t i = 0;
  for (const auto& [id, kf] : map().keyframes()) {
    EXPECT_NEAR(kfs.stamps[i], kf.t * 1e-9, 1e-9);
    const SE3 T_w_b = kf.T_w_c * T_body_camera.inverse();
    EXPECT_LT((kfs.poses[i].translation() - T_w_b.translation()).norm(), 1e-6);
    ++i;
  }
  write_points_ply((dir / "sparse.ply").string(), map());
  const std::string ply = read_bytes(dir / "sparse.ply");
  const std::string header_end = "end_header\n";
  const std::size_t body = ply.find(header_end);
  ASSERT_NE(body, std::string::npos);
  EXPECT_NE(ply.find("element vertex " + std::to_string(map().num_points()) + "\n"),
            std::string::npos);
  EXPECT_EQ(ply.size() - body - header_end.size(), map().num_points() * 13);
}

// Multi-session: a fresh tracker that loads the map relocalizes in it at the loop's end.
void MapIo::relocalize_at_loop_end(const tracking::TrackerOptions& options) {
  const auto dir = test::temp_dir("map_io_reloc");
  save_map((dir / "map.bin").string(), map());
  tracking::Tracker second(sim_->calibration().camera, options);
  second.set_map(load_map((dir / "map.bin").string()));
  EXPECT_EQ(second.state(), tracking::TrackingState::kLost);

  // The late frame nearest (position and heading) to a frame of the first session.
  const SE3 target = sim_->camera_pose(sim_->frame_time(kRevisitedFrame));
  int start = -1;
  double best = 1e9;
  for (int k = kFirstSessionFrames + 150; k < sim_->frame_count(); ++k) {
    const SE3 T = sim_->camera_pose(sim_->frame_time(k));
    const double d = (T.translation() - target.translation()).norm() +
                     (T.so3().inverse() * target.so3()).angle();
    if (d < best) {
      best = d;
      start = k;
    }
  }
  ASSERT_GE(start, 0);
  ASSERT_LT(best, 0.5) << "the path does not revisit the first session's place";
  int frames_to_relocalize = -1;
  for (int k = start; k < start + 30 && k < sim_->frame_count(); ++k) {
    const sim::SimFrame f = sim_->render(k);
    const tracking::TrackResult r = second.track(to_rgbd(f, sim_->calibration()));
    if (r.state == tracking::TrackingState::kRelocalized) {
      frames_to_relocalize = k - start;
      const double err = (r.T_w_c.translation() - sim_->camera_pose(f.time).translation()).norm();
      std::cout << "relocalized at frame " << k << " (" << k - start
                << " frames after t = " << f.time << " s), position error " << err * 100.0
                << " cm, " << r.inliers << " inliers\n";
      EXPECT_LT(err, 0.05);
      break;
    }
  }
  ASSERT_GE(frames_to_relocalize, 0) << "never relocalized";
  EXPECT_LE(frames_to_relocalize, 5);
  // And it keeps tracking in the loaded map afterwards.
  for (int k = start + frames_to_relocalize + 1; k < start + frames_to_relocalize + 10; ++k) {
    const sim::SimFrame f = sim_->render(k);
    const tracking::TrackResult r = second.track(to_rgbd(f, sim_->calibration()));
    EXPECT_EQ(r.state, tracking::TrackingState::kOk) << "frame " << k;
    EXPECT_LT((r.T_w_c.translation() - sim_->camera_pose(f.time).translation()).norm(), 0.05);
  }
}

TEST_F(MapIo, LoadedMapRelocalizesAtTheEndOfTheLoop) { relocalize_at_loop_end({}); }

// The same with a map too large to match whole: keyframe voting must pick the right place.
TEST_F(MapIo, LoadedMapRelocalizesThroughKeyframeVoting) {
  tracking::TrackerOptions options;
  options.relocalize_max_points = 250;
  ASSERT_GT(map().num_points(), 2u * 250u);
  relocalize_at_loop_end(options);
}

}  // namespace
}  // namespace kestrel::mapping
