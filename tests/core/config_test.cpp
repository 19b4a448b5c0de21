#include "core/config.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "core/error.hpp"
#include "tests/test_paths.hpp"

namespace kestrel {
namespace {

std::string error_of(const std::string& text, const std::string& name = "cfg.yaml") {
  try {
    parse_config(text, name);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Config, KestrelDialectRoundTrips) {
  Calibration c;
  c.camera.fx = 500.5;
  c.camera.model = DistortionModel::kRadTan;
  c.camera.dist = {0.1, -0.01, 0.001, 0.002, 0.0};
  c.right = c.camera;
  c.T_left_right = SE3(SO3(), Vec3(0.11, 0, 0));
  c.T_body_camera = SE3(SO3::exp(Vec3(0.1, 0.2, -0.3)), Vec3(0.01, 0.02, 0.03));
  c.has_imu = true;
  c.imu.gyro_noise = 1.6968e-4;
  c.depth_scale = 1000.0;
  c.fps = 20.0;
  const Config back = parse_config(to_yaml(c), "roundtrip.yaml");
  EXPECT_DOUBLE_EQ(back.calib.camera.fx, 500.5);
  EXPECT_EQ(back.calib.camera.model, DistortionModel::kRadTan);
  EXPECT_DOUBLE_EQ(back.calib.camera.dist[3], 0.002);
  ASSERT_TRUE(back.calib.right);
  EXPECT_NEAR(back.calib.T_left_right.translation().x(), 0.11, 1e-15);
  EXPECT_LT((back.calib.T_body_camera.matrix() - c.T_body_camera.matrix()).norm(), 1e-12);
  EXPECT_TRUE(back.calib.has_imu);
  EXPECT_DOUBLE_EQ(back.calib.imu.gyro_noise, 1.6968e-4);
  EXPECT_DOUBLE_EQ(back.calib.depth_scale, 1000.0);
  EXPECT_FALSE(back.calib.depth_max);  // unsaid stays unsaid
  c.depth_max = 13.0;
  const Config ranged = parse_config(to_yaml(c), "roundtrip.yaml");
  ASSERT_TRUE(ranged.calib.depth_max);
  EXPECT_DOUBLE_EQ(*ranged.calib.depth_max, 13.0);
  EXPECT_EQ(error_of("depth_max: -2\n"), "cfg.yaml:1: field 'depth_max': must be positive, got -2");
}

TEST(Config, ReadsOrbSlam3OldFormatWithOpenCvHeader) {
  const std::string text = R"(%YAML:1.0
Camera.type: "PinHole"
Camera.fx: 535.4
Camera.fy: 539.2
Camera.cx: 320.1
Camera.cy: 247.6
Camera.k1: 0.0
Camera.k2: 0.0
Camera.p1: 0.0
Camera.p2: 0.0
Camera.width: 640
Camera.height: 480
Camera.fps: 30.0
Camera.bf: 40.0
DepthMapFactor: 5000.0
Tbc: !!opencv-matrix
   rows: 4
   cols: 4
   dt: f
   data: [1.0, 0.0, 0.0, 0.1,
          0.0, 1.0, 0.0, 0.2,
          0.0, 0.0, 1.0, 0.3,
          0.0, 0.0, 0.0, 1.0]
IMU.NoiseGyro: 1.7e-4
IMU.NoiseAcc: 2.0e-3
IMU.GyroWalk: 1.9e-5
IMU.AccWalk: 3.0e-3
IMU.Frequency: 200
)";
  const Config cfg = parse_config(text, "TUM3.yaml");
  EXPECT_DOUBLE_EQ(cfg.calib.camera.fx, 535.4);
  EXPECT_EQ(cfg.calib.camera.model, DistortionModel::kNone);
  EXPECT_DOUBLE_EQ(cfg.calib.depth_scale, 5000.0);
  EXPECT_FALSE(cfg.calib.is_stereo());  // bf with a depth factor is RGB-D, not stereo
  EXPECT_TRUE(cfg.calib.has_imu);
  EXPECT_DOUBLE_EQ(cfg.calib.imu.rate_hz, 200.0);
  EXPECT_NEAR(cfg.calib.T_body_camera.translation().z(), 0.3, 1e-12);
}

TEST(Config, ReadsOrbSlam3V1StereoFisheye) {
  const std::string text = R"(%YAML:1.0
File.version: "1.0"
Camera.type: "KannalaBrandt8"
Camera1.fx: 190.978
Camera1.fy: 190.973
Camera1.cx: 254.932
Camera1.cy: 256.897
Camera1.k1: 0.0034823894
Camera1.k2: 0.00071506
Camera1.k3: -0.0020532362
Camera1.k4: 0.0002029343
Camera2.fx: 190.44
Camera2.fy: 190.43
Camera2.cx: 252.59
Camera2.cy: 254.91
Camera2.k1: 0.0034
Camera2.k2: 0.0007
Camera2.k3: -0.002
Camera2.k4: 0.0002
Camera.width: 512
Camera.height: 512
Stereo.T_c1_c2: !!opencv-matrix
  rows: 4
  cols: 4
  dt: f
  data: [1, 0, 0, 0.101, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
IMU.T_b_c1: !!opencv-matrix
  rows: 4
  cols: 4
  dt: f
  data: [1, 0, 0, 0.04, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
IMU.NoiseGyro: 0.00016
IMU.NoiseAcc: 0.0028
IMU.GyroWalk: 0.000022
IMU.AccWalk: 0.00086
IMU.Frequency: 200.0
)";
  const Config cfg = parse_config(text, "TUM-VI.yaml");
  EXPECT_EQ(cfg.calib.camera.model, DistortionModel::kEquidistant);
  EXPECT_DOUBLE_EQ(cfg.calib.camera.dist[3], 0.0002029343);
  ASSERT_TRUE(cfg.calib.is_stereo());
  EXPECT_DOUBLE_EQ(cfg.calib.right->fx, 190.44);
  EXPECT_NEAR(cfg.calib.stereo_rig().baseline(), 0.101, 1e-12);
  EXPECT_NEAR(cfg.calib.T_body_camera.translation().x(), 0.04, 1e-12);
  EXPECT_EQ(cfg.calib.camera.width, 512);
}

TEST(Config, ReadsEurocSensorYaml) {
  SE3 T_bc;
  const auto path = test::shared_data("euroc/V1_01_micro/mav0/cam0/sensor.yaml").string();
  const PinholeCamera cam = load_euroc_camera(path, &T_bc);
  EXPECT_DOUBLE_EQ(cam.fx, 458.654);
  EXPECT_DOUBLE_EQ(cam.cy, 248.375);
  EXPECT_EQ(cam.width, 752);
  EXPECT_EQ(cam.model, DistortionModel::kRadTan);
  EXPECT_DOUBLE_EQ(cam.dist[0], -0.28340811);
  EXPECT_NEAR(T_bc.translation().x(), -0.0216401454975, 1e-12);
  const ImuNoise imu =
      load_euroc_imu(test::shared_data("euroc/V1_01_micro/mav0/imu0/sensor.yaml").string());
  EXPECT_DOUBLE_EQ(imu.gyro_noise, 1.6968e-04);
  EXPECT_DOUBLE_EQ(imu.acc_walk, 3.0000e-3);
  EXPECT_DOUBLE_EQ(imu.rate_hz, 200.0);
}

TEST(Config, ErrorsNameFileLineAndField) {
  EXPECT_EQ(
      error_of("camera:\n  width: 640\n  height: 480\n  fx: abc\n  fy: 1\n  cx: 1\n  cy: 1\n"),
      "cfg.yaml:4: field 'camera.fx': expected a number, got 'abc'");
  EXPECT_EQ(error_of("camera:\n  width: 640\n  height: 480\n  fx: -5\n  fy: 1\n  cx: 1\n  cy: 1\n"),
            "cfg.yaml:4: field 'camera.fx': must be positive, got -5");
  EXPECT_NE(error_of("camera:\n  width: 640\n  height: 480\n").find("field 'camera.fx': missing"),
            std::string::npos);
  EXPECT_NE(error_of("imu: {gyro_noise: .nan}").find("field 'imu.gyro_noise': must be finite"),
            std::string::npos);
  EXPECT_NE(error_of("a: [1, 2\nb: 3\n").find("cfg.yaml:"), std::string::npos);
  EXPECT_NE(error_of("T_body_camera: [1, 2, 3]").find("expected 16 numbers"), std::string::npos);
  EXPECT_NE(error_of("T_body_camera: [2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]").find("not a rotation"),
            std::string::npos);
  EXPECT_NE(error_of("Camera.fx: 500\nCamera.fy: 500\nCamera.cx: 1\n").find("field 'Camera.cy'"),
            std::string::npos);
  try {
    load_config("/nonexistent/kestrel.yaml");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/kestrel.yaml: cannot open file");
  }
}

// Found by fuzz/config_parsers_fuzz.cpp: yaml-cpp's own exceptions escaped for a node of the
// wrong kind, and an EuRoC camera with a negative size parsed.
TEST(Config, WrongNodeKindsAndUnusableEurocValuesAreErrors) {
  EXPECT_NE(error_of("camera: [1, 2, 3]\n").find("cfg.yaml"), std::string::npos);
  EXPECT_NE(error_of("imu: 5\n").find("cfg.yaml"), std::string::npos);
  EXPECT_NE(error_of("camera:\n  - width\n  - height\n").find("cfg.yaml"), std::string::npos);
  const std::string euroc =
      "sensor_type: camera\nT_BS:\n  cols: 4\n  rows: 4\n  data: [1,0,0,0, 0,1,0,0, 0,0,1,0, "
      "0,0,0,1]\nresolution: [752, RES]\ncamera_model: pinhole\nintrinsics: [FX, 457.3, 367.2, "
      "248.4]\ndistortion_model: radial-tangential\ndistortion_coefficients: [0, 0, 0, 0]\n";
  auto with = [&](const std::string& res, const std::string& fx) {
    std::string t = euroc;
    t.replace(t.find("RES"), 3, res);
    t.replace(t.find("FX"), 2, fx);
    return t;
  };
  EXPECT_EQ(error_of(with("480", "458.6")), "");
  EXPECT_NE(error_of(with("-480", "458.6")).find("field 'resolution'"), std::string::npos);
  EXPECT_NE(error_of(with("480.5", "458.6")).find("field 'resolution'"), std::string::npos);
  EXPECT_NE(error_of(with("480", "0")).find("field 'intrinsics'"), std::string::npos);
}

TEST(Config, ShippedDefaultConfigLoads) {
  const Config cfg = load_config(std::string(KESTREL_SOURCE_DIR) + "/config/default.yaml");
  EXPECT_EQ(cfg.calib.camera.width, 640);
  EXPECT_TRUE(cfg.calib.has_imu);
}

}  // namespace
}  // namespace kestrel
