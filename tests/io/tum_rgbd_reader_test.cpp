#include "io/tum_rgbd_reader.hpp"

#include <gtest/gtest.h>

#include "io/image_io.hpp"
#include "tests/io/io_test_util.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

namespace fs = std::filesystem;
using test::shared_data;

const fs::path kFrame = shared_data("tum_fr3/frame");

// A TUM-layout folder with the real fr3 images copied under several stamps. Depth stamps are
// offset by a few ms as in the real recordings, one depth image has no partner within 0.02 s.
fs::path make_tum_folder(const std::string& name) {
  const fs::path dir = test::temp_dir(name) / "rgbd_dataset_freiburg3_walking_xyz";
  const char* rgb_stamps[] = {"1341846313.592026", "1341846313.654184", "1341846313.686156",
                              "1341846313.721918"};
  const char* depth_stamps[] = {"1341846313.592088", "1341846313.654212", "1341846313.686172",
                                "1341846313.721932", "1341846313.900000"};
  std::string rgb_txt =
      "# color images\n# file: 'rgbd_dataset_freiburg3_walking_xyz.bag'\n# timestamp filename\n";
  std::string depth_txt =
      "# depth maps\n# file: 'rgbd_dataset_freiburg3_walking_xyz.bag'\n# timestamp filename\n";
  for (const char* s : rgb_stamps) {
    test::copy(kFrame / "rgb_1341846313.592026.png", dir / "rgb" / (std::string(s) + ".png"));
    rgb_txt += std::string(s) + " rgb/" + s + ".png\n";
  }
  for (const char* s : depth_stamps) {
    test::copy(kFrame / "depth_1341846313.592088.png", dir / "depth" / (std::string(s) + ".png"));
    depth_txt += std::string(s) + " depth/" + s + ".png\n";
  }
  test::write_file(dir / "rgb.txt", rgb_txt);
  test::write_file(dir / "depth.txt", depth_txt);
  test::copy(shared_data("tum_fr3/groundtruth/fr3_walk_xyz.txt"), dir / "groundtruth.txt");
  return dir;
}

TEST(TumRgbdReader, ReadsFolderEndToEnd) {
  const fs::path dir = make_tum_folder("tum_e2e");
  auto src = open_tum_rgbd(dir.string());
  EXPECT_EQ(src->frame_count(), 4u);
  const Calibration& c = src->calibration();
  EXPECT_EQ(c.camera.fx, 535.4);
  EXPECT_EQ(c.camera.fy, 539.2);
  EXPECT_EQ(c.camera.cx, 320.1);
  EXPECT_EQ(c.camera.cy, 247.6);
  EXPECT_EQ(c.depth_scale, 5000.0);
  EXPECT_FALSE(c.has_imu);
  ASSERT_TRUE(src->ground_truth().has_value());
  EXPECT_GT(src->ground_truth()->size(), 100u);

  const Image ref_rgb =
      load_image((kFrame / "rgb_1341846313.592026.png").string(), ImageKind::kColor);
  const Image ref_depth =
      load_image((kFrame / "depth_1341846313.592088.png").string(), ImageKind::kDepth);
  const Timestamp expected[] = {1341846313592026000, 1341846313654184000, 1341846313686156000,
                                1341846313721918000};
  int n = 0;
  while (auto m = src->next()) {
    ASSERT_TRUE(std::holds_alternative<RgbdFrame>(*m));
    const RgbdFrame& f = std::get<RgbdFrame>(*m);
    EXPECT_EQ(f.t, expected[n]);
    EXPECT_EQ(*f.color.data, *ref_rgb.data);
    EXPECT_EQ(*f.depth.data, *ref_depth.data);
    EXPECT_EQ(f.depth_scale, 5000.0);
    ++n;
  }
  EXPECT_EQ(n, 4);
  EXPECT_NE(src->describe().find("4 of 4 rgb / 5 depth"), std::string::npos) << src->describe();
}

TEST(TumRgbdReader, UsesAssociationFile) {
  const fs::path dir = make_tum_folder("tum_assoc");
  test::write_file(
      dir / "my_assoc.txt",
      "1341846313.654184 rgb/1341846313.654184.png 1341846313.654212 depth/1341846313.654212.png\n"
      "1341846313.721918 rgb/1341846313.721918.png 1341846313.721932 "
      "depth/1341846313.721932.png\n");
  TumRgbdOptions o;
  o.association_file = "my_assoc.txt";
  auto src = open_tum_rgbd(dir.string(), o);
  EXPECT_EQ(src->frame_count(), 2u);
  auto m = src->next();
  ASSERT_TRUE(m);
  EXPECT_EQ(stamp_of(*m), 1341846313654184000);
}

TEST(TumRgbdReader, CalibrationByFolderName) {
  EXPECT_EQ(tum_calibration_for("rgbd_dataset_freiburg1_xyz")->camera.fx, 517.3);
  EXPECT_EQ(tum_calibration_for("rgbd_dataset_freiburg2_desk")->camera.cx, 325.1);
  EXPECT_EQ(tum_calibration_for("fr3_walking_xyz")->camera.fy, 539.2);
  EXPECT_EQ(tum_calibration_for("freiburg1")->camera.model, DistortionModel::kRadTan);
  EXPECT_FALSE(tum_calibration_for("my_office").has_value());
  EXPECT_FALSE(tum_calibration_for("fr12").has_value());
}

TEST(TumRgbdReader, UnknownCameraNeedsConfig) {
  const fs::path dir = test::temp_dir("tum_nocam");
  test::write_file(dir / "rgb.txt", "1.0 rgb/1.png\n");
  test::write_file(dir / "depth.txt", "1.0 depth/1.png\n");
  test::expect_error([&] { open_tum_rgbd(dir.string()); }, {dir.string(), "calib"});
}

TEST(TumRgbdReader, AccelerometerFile) {
  const fs::path dir = test::temp_dir("tum_acc");
  test::write_file(dir / "accelerometer.txt",
                   "# accelerometer data\n# timestamp ax ay az\n1305031098.6 -0.08 -9.5 -1.2\n"
                   "1305031098.61 -0.07 -9.6 -1.1\n");
  const auto acc = read_tum_accelerometer((dir / "accelerometer.txt").string());
  ASSERT_EQ(acc.size(), 2u);
  EXPECT_EQ(acc[1].t, 1305031098610000000);
  EXPECT_EQ(acc[0].v.y(), -9.5);
}

}  // namespace
}  // namespace kestrel::io
