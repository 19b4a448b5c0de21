#include "io/euroc_reader.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/io/io_test_util.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

namespace fs = std::filesystem;
const fs::path kMicro = test::shared_data("euroc/V1_01_micro");

std::size_t csv_rows(const fs::path& p) {
  std::ifstream in(p);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) n += !line.empty() && line[0] != '#';
  return n;
}

// Numbers as printed in mav0/cam0/sensor.yaml and cam1/sensor.yaml.
Mat4 T_BS_cam0() {
  Mat4 m;
  m << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008,
      0.0149672133247, 0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797,
      0.999660727178, 0.00981073058949, 0, 0, 0, 1;
  return m;
}
Mat4 T_BS_cam1() {
  Mat4 m;
  m << 0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556, 0.999598781151,
      0.0130119051815, 0.0251588363115, 0.0453689425024, -0.0253898008918, 0.0179005838253,
      0.999517347078, 0.00786212447038, 0, 0, 0, 1;
  return m;
}

TEST(EurocReader, MicroClipStream) {
  EurocReader src(kMicro.string());
  EXPECT_EQ(src.frame_count(), 95u);
  EXPECT_EQ(src.unmatched_left(), 0u);
  EXPECT_EQ(src.unmatched_right(), 4u);  // cam1/data.csv lists 4 stamps cam0 does not have
  const std::size_t imu_rows = csv_rows(kMicro / "mav0/imu0/data.csv");
  EXPECT_EQ(imu_rows, 29120u);
  EXPECT_EQ(src.imu_count(), imu_rows);

  std::size_t frames = 0, imu = 0;
  Timestamp last = 0;
  bool last_was_frame = false;
  Timestamp first_imu = 0, last_imu = 0;
  while (auto m = src.next()) {
    const Timestamp t = stamp_of(*m);
    if (frames + imu > 0) {
      EXPECT_GE(t, last);
      // Equal stamps: IMU first, so a frame is never followed by an IMU sample of its stamp.
      if (t == last) {
        EXPECT_FALSE(last_was_frame && std::holds_alternative<ImuSample>(*m));
      }
    }
    last = t;
    if (const auto* s = std::get_if<StereoFrame>(&*m)) {
      ++frames;
      last_was_frame = true;
      ASSERT_EQ(s->left.width, 752);
      ASSERT_EQ(s->left.height, 480);
      ASSERT_EQ(s->left.channels, 1);
      ASSERT_EQ(s->right.width, 752);
    } else {
      ASSERT_TRUE(std::holds_alternative<ImuSample>(*m));
      if (imu == 0) first_imu = t;
      last_imu = t;
      ++imu;
      last_was_frame = false;
    }
  }
  EXPECT_EQ(frames, 95u);
  EXPECT_EQ(imu, imu_rows);
  EXPECT_EQ(first_imu, 1403715273262142976);
  EXPECT_EQ(last_imu, 1403715418857143040);
  // The first frame and the first IMU sample share a stamp: the IMU sample came first.
  src.rewind();
  EXPECT_TRUE(std::holds_alternative<ImuSample>(*src.next()));
  EXPECT_TRUE(std::holds_alternative<StereoFrame>(*src.next()));
}

TEST(EurocReader, CalibrationMatchesSensorYaml) {
  EurocReader src(kMicro.string());
  const Calibration& c = src.calibration();
  EXPECT_EQ(c.camera.fx, 458.654);
  EXPECT_EQ(c.camera.fy, 457.296);
  EXPECT_EQ(c.camera.cx, 367.215);
  EXPECT_EQ(c.camera.cy, 248.375);
  EXPECT_EQ(c.camera.width, 752);
  EXPECT_EQ(c.camera.height, 480);
  EXPECT_EQ(c.camera.model, DistortionModel::kRadTan);
  EXPECT_EQ(c.camera.dist[0], -0.28340811);
  EXPECT_EQ(c.camera.dist[1], 0.07395907);
  EXPECT_EQ(c.camera.dist[2], 0.00019359);
  EXPECT_EQ(c.camera.dist[3], 1.76187114e-05);
  ASSERT_TRUE(c.right.has_value());
  EXPECT_EQ(c.right->fx, 457.587);
  EXPECT_EQ(c.right->cy, 255.238);
  EXPECT_EQ(c.right->dist[3], -3.55590700e-05);
  EXPECT_EQ(c.fps, 20.0);
  // imu0's T_BS is the identity, so body = IMU = the EuRoC body frame.
  EXPECT_LT((c.T_body_camera.matrix() - T_BS_cam0()).cwiseAbs().maxCoeff(), 1e-9);
  const Mat4 T_lr = T_BS_cam0().inverse() * T_BS_cam1();
  EXPECT_LT((c.T_left_right.matrix() - T_lr).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(c.T_left_right.translation().norm(), 0.110, 0.001);  // the VI-sensor baseline
  EXPECT_GT(c.T_left_right.translation().x(), 0.10);               // right camera is at +x
  ASSERT_TRUE(c.has_imu);
  EXPECT_EQ(c.imu.gyro_noise, 1.6968e-04);
  EXPECT_EQ(c.imu.gyro_walk, 1.9393e-05);
  EXPECT_EQ(c.imu.acc_noise, 2.0e-3);
  EXPECT_EQ(c.imu.acc_walk, 3.0e-3);
  EXPECT_EQ(c.imu.rate_hz, 200.0);
  // No state_groundtruth_estimate0/data.csv in the clip.
  EXPECT_FALSE(src.ground_truth().has_value());
  EXPECT_NE(src.describe().find("4 cam1"), std::string::npos) << src.describe();
}

TEST(EurocReader, MonocularOption) {
  EurocOptions o;
  o.stereo = false;
  EurocReader src(kMicro.string(), o);
  EXPECT_FALSE(src.calibration().is_stereo());
  EXPECT_EQ(src.frame_count(), 95u);
  while (auto m = src.next()) {
    if (const auto* f = std::get_if<RgbdFrame>(&*m)) {
      EXPECT_TRUE(f->depth.empty());
      EXPECT_EQ(f->color.channels, 1);
      break;
    }
    ASSERT_TRUE(std::holds_alternative<ImuSample>(*m));
  }
}

// TUM-VI: same ASL layout, equidistant cameras from a Kalibr camchain, ground truth in mocap0.
TEST(EurocReader, TumViLayoutWithCamchain) {
  const fs::path root = test::temp_dir("tumvi") / "dataset-room1_512_16";
  const fs::path mav = root / "mav0";
  const fs::path img = kMicro / "mav0/cam0/data/1403715273262142976.png";
  std::string cam_csv = "#timestamp [ns],filename\n";
  for (const char* t : {"1520530308199447626", "1520530308249448626"}) {
    test::copy(img, mav / "cam0/data" / (std::string(t) + ".png"));
    test::copy(img, mav / "cam1/data" / (std::string(t) + ".png"));
    cam_csv += std::string(t) + "," + t + ".png\n";
  }
  test::write_file(mav / "cam0/data.csv", cam_csv);
  test::write_file(mav / "cam1/data.csv", cam_csv);
  test::write_file(mav / "imu0/data.csv",
                   "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                   "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n"
                   "1520530308199447626,0.01,0.02,0.03,9.7,0.1,0.2\n"
                   "1520530308204447626,0.01,0.02,0.03,9.7,0.1,0.2\n");
  test::write_file(mav / "mocap0/data.csv",
                   "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x "
                   "[], q_RS_y [], q_RS_z []\n"
                   "1520530308199447626,0.1,0.2,0.3,1,0,0,0\n"
                   "1520530308249448626,0.2,0.2,0.3,1,0,0,0\n");
  test::write_file(root / "dso/camchain.yaml",
                   "cam0:\n"
                   "  T_cam_imu:\n"
                   "  - [-1.0, 0.0, 0.0, 0.0470]\n"
                   "  - [0.0, 0.0, -1.0, -0.0476]\n"
                   "  - [0.0, -1.0, 0.0, -0.0681]\n"
                   "  - [0.0, 0.0, 0.0, 1.0]\n"
                   "  camera_model: pinhole\n"
                   "  distortion_coeffs: [0.0034823894022493434, 0.0007150348452162257, "
                   "-0.0020532361418706202, 0.00020293673591811182]\n"
                   "  distortion_model: equidistant\n"
                   "  intrinsics: [190.97847715128717, 190.9733070521226, 254.93170605935475, "
                   "256.8974428996504]\n"
                   "  resolution: [512, 512]\n"
                   "cam1:\n"
                   "  T_cam_imu:\n"
                   "  - [-1.0, 0.0, 0.0, -0.0540]\n"
                   "  - [0.0, 0.0, -1.0, -0.0476]\n"
                   "  - [0.0, -1.0, 0.0, -0.0681]\n"
                   "  - [0.0, 0.0, 0.0, 1.0]\n"
                   "  distortion_coeffs: [0.0034, 0.0007, -0.0020, 0.0002]\n"
                   "  distortion_model: equidistant\n"
                   "  intrinsics: [190.44, 190.43, 252.59, 254.91]\n"
                   "  resolution: [512, 512]\n");
  EurocOptions o;
  o.name = "tumvi";
  EurocReader src(root.string(), o);
  const Calibration& c = src.calibration();
  EXPECT_EQ(c.camera.model, DistortionModel::kEquidistant);
  EXPECT_EQ(c.camera.fx, 190.97847715128717);
  EXPECT_EQ(c.camera.dist[3], 0.00020293673591811182);
  ASSERT_TRUE(c.right.has_value());
  EXPECT_EQ(c.right->cx, 252.59);
  // Both cameras share a rotation; the right one is 0.101 m along the left camera's x.
  EXPECT_NEAR(c.T_left_right.translation().norm(), 0.101, 1e-3);
  EXPECT_NEAR(c.T_body_camera.inverse().translation().x(), 0.0470, 1e-12);
  EXPECT_NEAR(c.T_left_right.translation().x(), 0.101, 1e-12);
  EXPECT_EQ(src.frame_count(), 2u);
  EXPECT_EQ(src.imu_count(), 2u);
  ASSERT_TRUE(src.ground_truth().has_value());
  EXPECT_EQ(src.ground_truth()->size(), 2u);
  EXPECT_EQ(src.describe().rfind("tumvi:", 0), 0u);
}

}  // namespace
}  // namespace kestrel::io
