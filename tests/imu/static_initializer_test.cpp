#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <random>

#include "imu/imu_initializer.hpp"
#include "io/text_lines.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::imu {
namespace {

const char* kImuCsv = "euroc/V1_01_micro/mav0/imu0/data.csv";
// EuRoC's state_groundtruth_estimate0/data.csv is not in the micro clip; OpenVINS' copy of the
// same ground truth (with b_w / b_a columns) is.
const char* kGroundTruthCsv = "euroc/V1_01_micro/groundtruth_open_vins/V1_01_easy.csv";

std::vector<ImuSample> read_euroc_imu(const std::filesystem::path& path) {
  const io::TextTable table = io::TextTable::read(path.string());
  std::vector<ImuSample> out;
  out.reserve(table.rows().size());
  for (const io::TextRow& row : table.rows()) {
    table.require_fields(row, 7, "timestamp, w_x, w_y, w_z, a_x, a_y, a_z");
    ImuSample s;
    s.t = table.nanoseconds(row, 0, "timestamp");
    s.gyro = Vec3(table.number(row, 1, "w_RS_S_x"), table.number(row, 2, "w_RS_S_y"),
                  table.number(row, 3, "w_RS_S_z"));
    s.acc = Vec3(table.number(row, 4, "a_RS_S_x"), table.number(row, 5, "a_RS_S_y"),
                 table.number(row, 6, "a_RS_S_z"));
    out.push_back(s);
  }
  return out;
}

struct GroundTruth {
  Timestamp t;
  SO3 R_w_b;
  Vec3 gyro_bias, acc_bias;
};

std::vector<GroundTruth> read_ground_truth(const std::filesystem::path& path) {
  const io::TextTable table = io::TextTable::read(path.string());
  std::vector<GroundTruth> out;
  for (const io::TextRow& row : table.rows()) {
    table.require_fields(row, 17, "time, p, q (w x y z), v, b_w, b_a");
    GroundTruth g;
    g.t = table.nanoseconds(row, 0, "time");
    g.R_w_b = SO3(Quat(table.number(row, 4, "qw"), table.number(row, 5, "qx"),
                       table.number(row, 6, "qy"), table.number(row, 7, "qz")));
    g.gyro_bias = Vec3(table.number(row, 11, "bwx"), table.number(row, 12, "bwy"),
                       table.number(row, 13, "bwz"));
    g.acc_bias = Vec3(table.number(row, 14, "bax"), table.number(row, 15, "bay"),
                      table.number(row, 16, "baz"));
    out.push_back(g);
  }
  return out;
}

TEST(StaticInitializer, EurocStillStartGivesGravityAndGyroBias) {
  const auto imu_path = test::shared_data(kImuCsv);
  const auto gt_path = test::shared_data(kGroundTruthCsv);
  ASSERT_TRUE(std::filesystem::exists(imu_path)) << imu_path;
  ASSERT_TRUE(std::filesystem::exists(gt_path)) << gt_path;
  const std::vector<ImuSample> imu = read_euroc_imu(imu_path);
  const std::vector<GroundTruth> gt = read_ground_truth(gt_path);
  ASSERT_GT(imu.size(), 1000u);
  ASSERT_FALSE(gt.empty());

  const StaticInitResult r = static_initialize(imu);
  ASSERT_TRUE(r.ok()) << to_string(r.status);
  const double still_s = to_seconds(r.still_end - r.still_begin);
  EXPECT_EQ(r.still_begin, imu.front().t);
  // The vehicle takes off about 5.5 s after the first camera frame (shared/data/README.md).
  EXPECT_GT(still_s, 4.0);
  EXPECT_LT(still_s, 10.0);

  // Ground truth over the clip (biases are estimated per stamp and barely move while still).
  Vec3 gt_bg = Vec3::Zero(), gt_ba = Vec3::Zero();
  for (const GroundTruth& g : gt) {
    gt_bg += g.gyro_bias;
    gt_ba += g.acc_bias;
  }
  gt_bg /= static_cast<double>(gt.size());
  gt_ba /= static_cast<double>(gt.size());
  const Vec3 up_gt = gt.front().R_w_b.inverse() * Vec3::UnitZ();
  const Vec3 up_est = r.R_w_b.inverse() * Vec3::UnitZ();
  const double tilt_err_deg = std::acos(std::clamp(up_gt.dot(up_est), -1.0, 1.0)) * 180.0 / M_PI;
  // Removing the ground-truth accelerometer bias should explain most of that tilt error.
  const Vec3 up_unbiased = (r.acc_mean - gt_ba).normalized();
  const double tilt_unbiased_deg =
      std::acos(std::clamp(up_gt.dot(up_unbiased), -1.0, 1.0)) * 180.0 / M_PI;

  std::printf("still %.2f s (%zu samples), |acc| %.4f m/s^2, gyro std %.4f, acc std %.4f\n",
              still_s, r.samples_used, r.acc_norm, r.gyro_std, r.acc_std);
  std::printf("gyro bias est  % .5f % .5f % .5f\n", r.gyro_bias.x(), r.gyro_bias.y(),
              r.gyro_bias.z());
  std::printf("gyro bias gt   % .5f % .5f % .5f  (|diff| %.2e rad/s)\n", gt_bg.x(), gt_bg.y(),
              gt_bg.z(), (r.gyro_bias - gt_bg).norm());
  std::printf("gravity direction error %.3f deg (%.3f deg after removing gt acc bias)\n",
              tilt_err_deg, tilt_unbiased_deg);

  EXPECT_NEAR(r.acc_norm, 9.81, 0.1);
  EXPECT_LT((r.gyro_bias - gt_bg).norm(), 2e-3);
  EXPECT_LT(tilt_err_deg, 1.0);
  EXPECT_LT(tilt_unbiased_deg, 0.5);
}

TEST(StaticInitializer, EurocFlightIsNotStill) {
  const auto imu_path = test::shared_data(kImuCsv);
  ASSERT_TRUE(std::filesystem::exists(imu_path)) << imu_path;
  const std::vector<ImuSample> imu = read_euroc_imu(imu_path);
  // 30 s after the start the vehicle is flying.
  std::vector<ImuSample> flight;
  for (const ImuSample& s : imu) {
    if (s.t > imu.front().t + 30 * kNanosPerSecond && s.t < imu.front().t + 40 * kNanosPerSecond) {
      flight.push_back(s);
    }
  }
  ASSERT_GT(flight.size(), 1000u);
  EXPECT_EQ(static_initialize(flight).status, StaticInitStatus::kNotStill);
}

std::vector<ImuSample> still_samples(const SO3& R_w_b, double seconds, double g, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<ImuSample> out;
  for (int k = 0; k <= static_cast<int>(seconds * 200); ++k) {
    ImuSample s;
    s.t = k * 5'000'000LL;
    s.gyro = Vec3(0.01, -0.02, 0.005) + 0.003 * Vec3(n(rng), n(rng), n(rng));
    s.acc = R_w_b.inverse() * Vec3(0, 0, g) + 0.03 * Vec3(n(rng), n(rng), n(rng));
    out.push_back(s);
  }
  return out;
}

TEST(StaticInitializer, SyntheticTiltIsRecovered) {
  const SO3 R = SO3::exp(Vec3(0.0, 0.0, 0.7)) * SO3::exp(Vec3(0.3, -0.5, 0.0));
  const StaticInitResult r = static_initialize(still_samples(R, 3.0, 9.81, 1));
  ASSERT_TRUE(r.ok());
  const Vec3 up = R.inverse() * Vec3::UnitZ();
  EXPECT_LT((r.R_w_b.inverse() * Vec3::UnitZ() - up).norm(), 2e-3);
  // Yaw is set to zero: the body x axis has no world-y component when rotated back.
  EXPECT_NEAR((r.R_w_b * Vec3::UnitX()).y(), 0.0, 1e-12);
  EXPECT_LT((r.gyro_bias - Vec3(0.01, -0.02, 0.005)).norm(), 1e-3);
}

TEST(StaticInitializer, ReportsBadInput) {
  EXPECT_EQ(static_initialize({}).status, StaticInitStatus::kTooFewSamples);
  EXPECT_EQ(static_initialize(still_samples(SO3(), 0.5, 9.81, 2)).status,
            StaticInitStatus::kTooFewSamples);
  EXPECT_EQ(static_initialize(still_samples(SO3(), 3.0, 12.0, 3)).status,
            StaticInitStatus::kBadGravityMagnitude);
  auto nan = still_samples(SO3(), 3.0, 9.81, 4);
  for (auto& s : nan) s.acc.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(static_initialize(nan).status, StaticInitStatus::kNotStill);
}

TEST(StaticInitializer, GravityAlignedRotationHandlesEveryUpDirection) {
  for (const Vec3& up : {Vec3(0, 0, 1), Vec3(0, 0, -1), Vec3(1, 0, 0), Vec3(-1, 0, 0),
                         Vec3(0, 1, 0), Vec3(0.3, -0.4, 0.2)}) {
    const SO3 R = gravity_aligned_rotation(up);
    EXPECT_LT((R * up.normalized() - Vec3::UnitZ()).norm(), 1e-12) << up.transpose();
  }
}

}  // namespace
}  // namespace kestrel::imu
