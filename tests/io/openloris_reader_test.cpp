#include "io/openloris_reader.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "io/image_io.hpp"
#include "tests/io/io_test_util.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

namespace fs = std::filesystem;

constexpr long long kT0us = 1560004885446165;  // microseconds
std::string stamp_us(long long us) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%lld.%06lld", us / 1000000, us % 1000000);
  return buf;
}

// A small cafe1-1-like folder in the layout the OpenLORIS-Scene tools read.
fs::path make_openloris(const std::string& name) {
  const fs::path dir = test::temp_dir(name) / "cafe1-1";
  const fs::path frame = test::shared_data("tum_fr3/frame");
  std::string color = "#Time color\n", depth = "#Time aligned_depth\n";
  const double t0 = 1560004885.446165;
  for (int i = 0; i < 3; ++i) {
    char c[32], d[32];
    std::snprintf(c, sizeof(c), "%.6f", t0 + i / 30.0);
    std::snprintf(d, sizeof(d), "%.6f", t0 + i / 30.0 + 0.004);
    test::copy(frame / "rgb_1341846313.592026.png", dir / "color" / (std::string(c) + ".png"));
    test::copy(frame / "depth_1341846313.592088.png",
               dir / "aligned_depth" / (std::string(d) + ".png"));
    color += std::string(c) + " color/" + c + ".png\n";
    depth += std::string(d) + " aligned_depth/" + d + ".png\n";
  }
  test::write_file(dir / "color.txt", color);
  test::write_file(dir / "aligned_depth.txt", depth);
  // Accelerometer at 250 Hz, gyroscope at 400 Hz; a_x = 10 * (t - t0) so interpolation is exact.
  std::string acc = "#Time Ax Ay Az\n", gyro = "#Time Gx Gy Gz\n";
  for (int i = 0; i <= 25; ++i) {
    const long long us = kT0us - 10000 + i * 4000;
    char line[96];
    std::snprintf(line, sizeof(line), " %.17g -9.81 0.1\n",
                  10.0 * static_cast<double>(us - kT0us) * 1e-6);
    acc += stamp_us(us) + line;
  }
  for (int i = 0; i < 50; ++i) {
    char line[96];
    std::snprintf(line, sizeof(line), " 0.001 -0.002 %.17g\n", 0.01 * i);
    gyro += stamp_us(kT0us - 20000 + i * 2500) + line;
  }
  test::write_file(dir / "d400_accelerometer.txt", acc);
  test::write_file(dir / "d400_gyroscope.txt", gyro);
  test::write_file(dir / "groundtruth.txt",
                   "# timestamp tx ty tz qx qy qz qw\n"
                   "1560004885.446165 0.1 0.2 0.3 0 0 0 1\n"
                   "1560004885.479522 0.11 0.2 0.3 0 0 0 1\n");
  test::write_file(dir / "sensors.yaml",
                   "%YAML:1.0\n"
                   "d400_color_optical_frame:\n"
                   "   sensor_type: camera\n"
                   "   sensor_name: d400_color_optical_frame\n"
                   "   fps: 30\n"
                   "   width: 640\n"
                   "   height: 480\n"
                   "   model: pinhole\n"
                   "   intrinsics: !!opencv-matrix\n"
                   "      rows: 1\n"
                   "      cols: 4\n"
                   "      dt: d\n"
                   "      data: [ 6.1145098876953125e+02, 6.1148571777343750e+02,\n"
                   "          4.3320397949218750e+02, 2.4947302246093750e+02 ]\n"
                   "   distortion_model: Inverse Brown Conrady\n"
                   "   distortion_coefficients: !!opencv-matrix\n"
                   "      rows: 1\n"
                   "      cols: 5\n"
                   "      dt: d\n"
                   "      data: [ 0., 0., 0., 0., 0. ]\n"
                   "d400_gyroscope:\n"
                   "   sensor_type: imu\n"
                   "   fps: 400\n"
                   "   noise_variances: [ 4.0e-06, 4.0e-06, 9.0e-06 ]\n"
                   "   bias_variances: [ 1.0e-10, 1.0e-10, 1.0e-10 ]\n"
                   "d400_accelerometer:\n"
                   "   sensor_type: imu\n"
                   "   fps: 250\n"
                   "   noise_variances: [ 1.0e-04, 1.0e-04, 1.0e-04 ]\n"
                   "   bias_variances: [ 1.0e-08, 1.0e-08, 1.0e-08 ]\n");
  test::write_file(dir / "trans_matrix.yaml",
                   "%YAML:1.0\n"
                   "trans_matrix:\n"
                   "  - { child_frame: d400_color_optical_frame, parent_frame: base_link, matrix: "
                   "!!opencv-matrix { rows: 4, cols: 4, dt: d, data: [0,0,1,0.2, -1,0,0,0.0, "
                   "0,-1,0,0.5, 0,0,0,1] } }\n"
                   "  - { child_frame: d400_imu, parent_frame: d400_color_optical_frame, matrix: "
                   "!!opencv-matrix { rows: 4, cols: 4, dt: d, data: [1,0,0,0.0203, 0,1,0,-0.0051, "
                   "0,0,1,-0.0112, 0,0,0,1] } }\n");
  return dir;
}

TEST(OpenLorisReader, ReadsSyntheticFolder) {
  const fs::path dir = make_openloris("loris");
  auto src = open_openloris(dir.string());
  const Calibration& c = src->calibration();
  EXPECT_EQ(c.camera.fx, 611.45098876953125);
  EXPECT_EQ(c.camera.fy, 611.48571777343750);
  EXPECT_EQ(c.camera.cx, 433.20397949218750);
  EXPECT_EQ(c.camera.width, 640);
  EXPECT_EQ(c.camera.model, DistortionModel::kNone);
  EXPECT_EQ(c.depth_scale, 1000.0);
  EXPECT_EQ(c.fps, 30.0);
  EXPECT_TRUE(c.has_imu);
  EXPECT_NEAR(c.imu.gyro_noise, std::sqrt(9.0e-6) / std::sqrt(400.0), 1e-15);
  EXPECT_NEAR(c.imu.acc_walk, std::sqrt(1.0e-8) * std::sqrt(250.0), 1e-15);
  EXPECT_EQ(c.imu.rate_hz, 400.0);
  // T_imu_color = (T_color_imu)^-1: the IMU sits at (0.0203, -0.0051, -0.0112) in colour.
  EXPECT_LT((c.T_body_camera.inverse().translation() - Vec3(0.0203, -0.0051, -0.0112)).norm(),
            1e-12);
  ASSERT_TRUE(src->ground_truth());
  EXPECT_EQ(src->ground_truth()->size(), 2u);
  EXPECT_EQ(src->frame_count(), 3u);

  std::size_t frames = 0, imu = 0;
  Timestamp last = 0;
  while (auto m = src->next()) {
    EXPECT_GE(stamp_of(*m), last);
    last = stamp_of(*m);
    if (const auto* s = std::get_if<ImuSample>(&*m)) {
      ++imu;
      // a_x = 10 (t - t0) interpolated at gyro stamps.
      const double t_rel = static_cast<double>(s->t - 1560004885446165000) * 1e-9;
      EXPECT_NEAR(s->acc.x(), 10.0 * t_rel, 1e-6);
      EXPECT_EQ(s->acc.y(), -9.81);
      EXPECT_EQ(s->gyro.x(), 0.001);
    } else {
      const RgbdFrame& f = std::get<RgbdFrame>(*m);
      ++frames;
      EXPECT_EQ(f.depth.type, PixelType::kU16);
      EXPECT_EQ(f.depth_scale, 1000.0);
    }
  }
  EXPECT_EQ(frames, 3u);
  // Gyro spans t0-0.02 .. t0+0.1025 every 2.5 ms; acc spans t0-0.01 .. t0+0.09.
  EXPECT_EQ(imu, 41u);
}

TEST(OpenLorisReader, MergeKeepsGyroStampsInsideAccelSpan) {
  const std::vector<StampedVector> acc = {{100, Vec3(0, 0, 0)}, {200, Vec3(10, 0, 0)}};
  const std::vector<StampedVector> gyro = {{50, Vec3(1, 1, 1)},
                                           {100, Vec3(2, 2, 2)},
                                           {150, Vec3(3, 3, 3)},
                                           {200, Vec3(4, 4, 4)},
                                           {250, Vec3(5, 5, 5)}};
  const auto s = merge_accel_gyro(acc, gyro);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].t, 100);
  EXPECT_EQ(s[1].acc.x(), 5.0);
  EXPECT_EQ(s[2].acc.x(), 10.0);
  EXPECT_EQ(s[2].gyro.x(), 4.0);
}

}  // namespace
}  // namespace kestrel::io
