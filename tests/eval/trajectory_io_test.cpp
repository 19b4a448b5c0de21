#include "io/trajectory_io.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "core/error.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(TrajectoryIo, DetectsFormatsOfRealFiles) {
  const auto evo = [](const std::string& f) { return test::shared_data("evo/" + f).string(); };
  const PoseSeries kitti = read_pose_series(evo("KITTI_00_gt.txt"));
  EXPECT_EQ(kitti.format, TrajectoryFormat::kKitti);
  EXPECT_FALSE(kitti.stamped);
  EXPECT_EQ(kitti.size(), 4541u);
  EXPECT_DOUBLE_EQ(kitti.poses[1](2, 3), 8.586941e-01);  // kept as written

  const PoseSeries timed = read_pose_series(evo("KITTI_00_gt.txt"), evo("KITTI_00_gt_times.txt"));
  EXPECT_TRUE(timed.stamped);
  EXPECT_DOUBLE_EQ(timed.stamps[1], 1.037359e-01);

  const PoseSeries euroc = read_pose_series(evo("V102_groundtruth.csv"));
  EXPECT_EQ(euroc.format, TrajectoryFormat::kEuroc);
  EXPECT_DOUBLE_EQ(euroc.stamps[0], 1403715524907143168.0 / 1e9);
  EXPECT_DOUBLE_EQ(euroc.poses[0](0, 3), 0.515356);

  const PoseSeries tum = read_pose_series(evo("V102.txt"));
  EXPECT_EQ(tum.format, TrajectoryFormat::kTum);
  EXPECT_EQ(tum.size(), 807u);
  const Trajectory traj = read_trajectory(evo("freiburg1_xyz-groundtruth.txt"));
  EXPECT_GT(traj.size(), 2900u);
}

TEST(TrajectoryIo, QuaternionMatrixMatchesEigen) {
  const Quat q = Quat(0.3, -0.5, 0.2, 0.7).normalized();
  const Mat4 m = pose_matrix(1, 2, 3, q.w(), q.x(), q.y(), q.z());
  EXPECT_LT((m.topLeftCorner<3, 3>() - q.toRotationMatrix()).norm(), 1e-15);
  EXPECT_EQ((Vec3(m.topRightCorner<3, 1>())), Vec3(1, 2, 3));
}

TEST(TrajectoryIo, TumRoundTripIsExact) {
  const std::string text =
      "1.5 0.1 0.2 0.3 0 0 0.38941834230865 0.921060994002885\n"
      "2.000000001 -1e-3 5 6 0.5 0.5 0.5 0.5\n"
      "3.25 1 1 1 0 0 0 1\n";
  const Trajectory a = parse_trajectory(text, "a.txt");
  const std::string path = (test::temp_dir("tum_round_trip") / "out.txt").string();
  write_tum(path, a);
  const Trajectory b = read_trajectory(path);
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.stamps[i], b.stamps[i]);
    EXPECT_EQ(a.poses[i].translation(), b.poses[i].translation());
    // The rotation goes through a matrix on reading, so the quaternion may move by an ulp.
    EXPECT_LT((a.poses[i].quaternion().coeffs() - b.poses[i].quaternion().coeffs()).norm(), 1e-15);
  }
}

// Found by fuzz/trajectory_parsers_fuzz.cpp: a TUM stamp that prints as a long integer read
// back as EuRoC nanoseconds.
TEST(TrajectoryIo, TumWriterKeepsIntegerStampsInSeconds) {
  Trajectory t;
  t.stamps = {13050311021750.0, 13050311021751.0};
  t.poses = {SE3(), SE3()};
  const Trajectory again = parse_trajectory(format_tum(t), "mem");
  ASSERT_EQ(again.size(), 2u);
  EXPECT_EQ(again.stamps[0], t.stamps[0]);
  EXPECT_EQ(again.stamps[1], t.stamps[1]);
}

TEST(TrajectoryIo, MalformedLineNamesFileLineAndField) {
  const std::string msg =
      error_of([] { parse_pose_series("1 0 0 0 0 0 0 1\n2 0 0 x 0 0 0 1\n", "traj.txt"); });
  EXPECT_NE(msg.find("traj.txt:2"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'tz'"), std::string::npos) << msg;
  const std::string short_row = error_of([] {
    parse_pose_series("1 0 0 0 0 0 0 1\n# comment\n2 0 0 0 0 0 1\n", "traj.txt",
                      TrajectoryFormat::kTum);
  });
  EXPECT_NE(short_row.find("traj.txt:3"), std::string::npos) << short_row;
  EXPECT_NE(short_row.find("expected 8 fields"), std::string::npos) << short_row;
}

TEST(TrajectoryIo, MissingFileIsNamed) {
  const std::string msg = error_of([] { read_pose_series("/nonexistent/poses.txt"); });
  EXPECT_NE(msg.find("/nonexistent/poses.txt"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cannot open"), std::string::npos) << msg;
}

TEST(TrajectoryIo, NanAndInfAreRejected) {
  const std::string nan = error_of([] { parse_pose_series("1 0 nan 0 0 0 0 1\n", "n.txt"); });
  EXPECT_NE(nan.find("n.txt:1"), std::string::npos) << nan;
  EXPECT_NE(nan.find("'ty'"), std::string::npos) << nan;
  EXPECT_NE(nan.find("finite"), std::string::npos) << nan;
  const std::string inf = error_of(
      [] { parse_pose_series("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 -inf\n", "k.txt"); });
  EXPECT_NE(inf.find("k.txt:2"), std::string::npos) << inf;
  EXPECT_NE(inf.find("'T23'"), std::string::npos) << inf;
}

TEST(TrajectoryIo, NonMonotonicStampsAreRejected) {
  const std::string msg = error_of([] {
    parse_pose_series("# t x y z qx qy qz qw\n1 0 0 0 0 0 0 1\n3 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n",
                      "order.txt");
  });
  EXPECT_NE(msg.find("order.txt:4"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'timestamp'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("must not decrease"), std::string::npos) << msg;
  // Repeated stamps occur in real ground truth (TUM fr3/walking_static, fr2/desk) and both
  // tools accept them, so they are kept.
  EXPECT_EQ(parse_pose_series("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", "dup.txt").size(), 2u);
}

TEST(TrajectoryIo, QuaternionNormIsChecked) {
  // 6-decimal rounding is fine and gets normalized...
  const PoseSeries ok = parse_pose_series("1 0 0 0 0.000001 0 0 1.000001\n", "q.txt");
  EXPECT_NEAR((ok.poses[0].block<3, 3>(0, 0).determinant()), 1.0, 1e-12);
  // ...a zero or clearly non-unit quaternion is an error at its line.
  const std::string zero = error_of([] { parse_pose_series("1 0 0 0 0 0 0 0\n", "q.txt"); });
  EXPECT_NE(zero.find("q.txt:1"), std::string::npos) << zero;
  EXPECT_NE(zero.find("zero quaternion"), std::string::npos) << zero;
  const std::string big = error_of([] { parse_pose_series("1 0 0 0 0 0 0 2\n", "q.txt"); });
  EXPECT_NE(big.find("not a unit quaternion"), std::string::npos) << big;
}

TEST(TrajectoryIo, KittiChecksRotationAndTimes) {
  const std::string bad_rot =
      error_of([] { parse_pose_series("2 0 0 0 0 1 0 0 0 0 1 0\n", "r.txt"); });
  EXPECT_NE(bad_rot.find("r.txt:1"), std::string::npos) << bad_rot;
  EXPECT_NE(bad_rot.find("rotation"), std::string::npos) << bad_rot;

  const auto dir = test::temp_dir("kitti_times");
  const std::string poses = (dir / "poses.txt").string();
  const std::string times = (dir / "times.txt").string();
  std::ofstream(poses) << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n";
  std::ofstream(times) << "0.0\n";
  const std::string count = error_of([&] { read_pose_series(poses, times); });
  EXPECT_NE(count.find(times), std::string::npos) << count;
  EXPECT_NE(count.find("1 stamps for 2 poses"), std::string::npos) << count;
}

TEST(TrajectoryIo, UnknownLayoutIsNamed) {
  const std::string msg = error_of([] { parse_pose_series("1 2 3\n", "odd.txt"); });
  EXPECT_NE(msg.find("odd.txt:1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cannot tell the trajectory format"), std::string::npos) << msg;
  const std::string empty = error_of([] { parse_pose_series("# only a comment\n", "e.txt"); });
  EXPECT_NE(empty.find("no poses"), std::string::npos) << empty;
}

}  // namespace
}  // namespace kestrel::io
