#include "pipeline/sequence_object_truth.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/error.hpp"
#include "io/dataset.hpp"
#include "pipeline/run_job.hpp"
#include "sim/mover_path.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::pipeline {
namespace {

constexpr double kFps = 30.0;

Timestamp frame_t(int k) { return from_seconds(k / kFps); }

io::SequenceBox box(int k, int instance, const std::string& label, double w, double h,
                    double occluded = 0.0) {
  io::SequenceBox b;
  b.t = frame_t(k);
  b.instance = instance;
  b.label = label;
  b.x_min = 100, b.y_min = 100, b.x_max = 100 + w, b.y_max = 100 + h;
  b.occluded = occluded;
  return b;
}

io::SequenceObject object(int id, const std::string& label, const Vec3& c) {
  io::SequenceObject o;
  o.id = id;
  o.label = label;
  o.center = c;
  o.size = Vec3(0.5, 0.5, 0.95);
  return o;
}

// A camera at the origin for 4 s of frames, a sensor ranging 8 m.
ObjectTruthInput still_camera() {
  ObjectTruthInput in;
  in.depth_max = 8.0;
  in.end_s = 4.0;
  in.camera_position = [](Timestamp t) -> std::optional<Vec3> {
    if (t < 0 || t > from_seconds(4.0)) return std::nullopt;
    return Vec3::Zero();
  };
  return in;
}

bool has(const std::vector<eval::ObjectBox>& v, const std::string& label, const Vec3& c) {
  for (const auto& b : v)
    if (b.label == label && (b.center - c).norm() < 1e-6) return true;
  return false;
}

TEST(ObjectTruth, AStaticObjectCountsOnlyWhenSeenLargeUnoccludedAndInRangeOftenEnough) {
  ObjectTruthInput in = still_camera();
  in.objects = {object(1000, "chair", {2, 0, 0.475}), object(1001, "chair", {3, 0, 0.475}),
                object(1002, "couch", {4, 0, 0.42}), object(1003, "tv", {7.8, 0, 1.6}),
                object(1004, "bench", {5, 0, 0.25})};
  for (int k = 0; k < 30; ++k) in.boxes.push_back(box(k, 1000, "chair", 40, 40));
  for (int k = 0; k < 29; ++k) in.boxes.push_back(box(k, 1001, "chair", 40, 40));  // too rarely
  for (int k = 0; k < 60; ++k) in.boxes.push_back(box(k, 1002, "couch", 19, 20));  // too small
  for (int k = 0; k < 60; ++k) in.boxes.push_back(box(k, 1003, "tv", 60, 40));     // too far
  for (int k = 0; k < 60; ++k) in.boxes.push_back(box(k, 1004, "bench", 60, 40, 0.6));
  const auto truth = object_truth(in).visible;
  ASSERT_EQ(truth.size(), 1u);
  EXPECT_TRUE(has(truth, "chair", {2, 0, 0.475}));
  EXPECT_EQ(truth[0].size, Vec3(0.5, 0.5, 0.95));
}

TEST(ObjectTruth, AFrameWithoutATruePoseDoesNotCount) {
  ObjectTruthInput in = still_camera();
  in.objects = {object(1000, "chair", {2, 0, 0.475})};
  // 40 frames, 15 of them after the truth ends.
  for (int k = 95; k < 135; ++k) in.boxes.push_back(box(k, 1000, "chair", 40, 40));
  EXPECT_TRUE(object_truth(in).visible.empty());
}

TEST(ObjectTruth, APushedChairCountsWhereItStopsAndAWalkerNever) {
  ObjectTruthInput in = still_camera();
  sim::MoverSpec chair;
  chair.type = "chair";
  chair.label = "chair";
  chair.path = {Vec3(3, -1, 0), Vec3(3, 0, 0)};
  chair.speed = 1.0;
  chair.start = 1.0;  // moves from 1 s to 2 s
  chair.mode = "once";
  chair.size = Vec3(0.5, 0.5, 0.95);
  sim::MoverSpec walker;
  walker.type = "person";
  walker.path = {Vec3(2, -2, 0), Vec3(2, 2, 0)};
  walker.speed = 0.0001;  // as good as standing: a person is never an object all the same
  in.movers = {chair, walker};
  for (int k = 0; k < 120; ++k) {
    in.boxes.push_back(box(k, 1, "chair", 40, 60));
    in.boxes.push_back(box(k, 2, "person", 40, 100));
  }
  const auto truth = object_truth(in).visible;
  ASSERT_EQ(truth.size(), 1u);
  EXPECT_TRUE(has(truth, "chair", {3, 0, 0.475})) << truth[0].center.transpose();

  // Seen only before it moved (where it no longer stands), it does not count.
  in.boxes.clear();
  for (int k = 0; k < 29; ++k) in.boxes.push_back(box(k, 1, "chair", 40, 60));
  EXPECT_TRUE(object_truth(in).visible.empty());
}

TEST(ObjectTruth, AMoverOnALoopOnlyPassesItsFinalPlace) {
  ObjectTruthInput in = still_camera();
  sim::MoverSpec car;
  car.type = "vehicle";
  car.label = "car";
  car.path = {Vec3(3, -2, 0), Vec3(3, 2, 0), Vec3(5, 2, 0), Vec3(5, -2, 0)};
  car.speed = 2.0;
  car.mode = "loop";
  car.size = Vec3(4.2, 1.8, 1.5);
  in.movers = {car};
  for (int k = 0; k < 120; ++k) in.boxes.push_back(box(k, 1, "car", 100, 60));
  EXPECT_TRUE(object_truth(in).visible.empty());
}

TEST(ObjectTruth, PrecisionIsAgainstTheWholeWorldRecallAgainstWhatWasSeen) {
  ObjectTruthInput in = still_camera();
  in.objects = {object(1000, "chair", {2, 0, 0.475}), object(1001, "couch", {3, 1, 0.42})};
  for (int k = 0; k < 40; ++k) in.boxes.push_back(box(k, 1000, "chair", 40, 40));
  for (int k = 0; k < 10; ++k) in.boxes.push_back(box(k, 1001, "couch", 80, 40));  // glimpsed
  const ObjectTruth truth = object_truth(in);
  ASSERT_EQ(truth.visible.size(), 1u);
  ASSERT_EQ(truth.world.size(), 2u);
  // The chair, the glimpsed couch (real: no false report) and a table that is not there.
  const std::vector<eval::ObjectBox> reported = {
      {"chair", {2.05, 0, 0.475}, {0.5, 0.5, 0.95}, 0, 5},
      {"couch", {3, 1.02, 0.42}, {0.5, 0.5, 0.95}, 0, 3},
      {"dining table", {-2, -2, 0.4}, {1, 1, 0.75}, 0, 4}};
  const eval::ObjectScores s = score_run_objects(truth, reported);
  EXPECT_EQ(s.truth, 1);
  EXPECT_EQ(s.reported, 3);
  EXPECT_DOUBLE_EQ(s.recall, 1.0);
  EXPECT_NEAR(s.precision, 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(s.center_error_median, 0.05, 1e-9);
  int extra = 0;
  for (const std::string& l : s.lines) {
    if (l.rfind("extra", 0) != 0) continue;
    ++extra;
    EXPECT_NE(l.find("dining table"), std::string::npos) << l;
  }
  EXPECT_EQ(extra, 1);
}

TEST(ObjectTruth, AFolderWithoutItsWorldGivesNothingAndABrokenFileIsNamed) {
  const std::string dir = test::temp_dir("object-truth-files").string();
  Trajectory gt;
  gt.push_back(0.0, SE3());
  EXPECT_FALSE(read_object_truth(dir, gt, SE3()).has_value());
  std::ofstream(dir + "/objects.json") << "[{\"label\": 3}]";
  std::ofstream(dir + "/boxes.csv") << "#stamp,instance,label,x_min,y_min,x_max,y_max,moving,"
                                       "occluded\n";
  std::ofstream(dir + "/scenario.yaml") << "name: x\n";
  try {
    (void)read_object_truth(dir, gt, SE3());
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("objects.json"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// The whole run: SLAM poses, the mapping thread's database, the oracle's boxes. A short cafe
// (6 s) whose tables and chairs the camera passes; every object the truth counts is found.
TEST(ObjectTruth, ARunOverASimulatedSequenceScoresItsObjectsAgainstTheWorld) {
  const std::string dir = (test::temp_dir("object-truth-run") / "cafe").string();
  {
    sim::ScenarioOverrides over;
    over.duration = 6.0;
    sim::Simulator sim(sim::load_scenario("cafe", over));
    sim::record_sequence(sim, dir);
  }
  auto source = io::open_dataset("kestrel:" + dir);
  RunOptions opt;
  opt.dataset_dir = dir;
  opt.detector = "oracle";
  opt.progress = false;
  const RunSummary s = run_sequence(*source, opt);
  ASSERT_TRUE(s.objects.has_value());
  const eval::ObjectScores& o = *s.objects;
  for (const std::string& line : o.lines) std::printf("  %s\n", line.c_str());
  EXPECT_GE(o.truth, 3);
  EXPECT_GE(o.recall, 0.9);
  // 6 s give a glimpse or two of a far object, from which a wrong one may come (a couch 1.8 m
  // off from 3 views at the edge of the image); over 30 s of the same world: 8 of 8, none
  // false.
  EXPECT_GE(o.precision, 0.8);
  EXPECT_LE(o.center_error_median, 0.10);
  EXPECT_NE(summary_json(s).find("\"objects\""), std::string::npos);

  // Without a detector the database stays empty: nothing found, and the score says so.
  auto again = io::open_dataset("kestrel:" + dir);
  opt.detector = "none";
  const RunSummary none = run_sequence(*again, opt);
  ASSERT_TRUE(none.objects.has_value());
  EXPECT_EQ(none.objects->reported, 0);
  EXPECT_EQ(none.objects->recall, 0.0);

  // A world file that cannot be read costs the score, not the run or its outputs.
  std::ofstream(dir + "/scenario.yaml") << "name: [unclosed\n";
  auto broken = io::open_dataset("kestrel:" + dir);
  opt.out_dir = test::temp_dir("object-truth-out").string();
  const RunSummary unscored = run_sequence(*broken, opt);
  EXPECT_FALSE(unscored.objects.has_value());
  EXPECT_NE(unscored.objects_error.find("scenario.yaml"), std::string::npos)
      << unscored.objects_error;
  EXPECT_TRUE(std::filesystem::exists(opt.out_dir + "/trajectory.txt"));
  EXPECT_NE(summary_json(unscored).find("objects_error"), std::string::npos);
  std::filesystem::remove_all(opt.out_dir);
  std::filesystem::remove_all(std::filesystem::path(dir).parent_path());
}

}  // namespace
}  // namespace kestrel::pipeline
