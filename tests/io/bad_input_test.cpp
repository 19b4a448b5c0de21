// Every malformed input gives a kestrel::Error naming the file and the line.
#include <gtest/gtest.h>

#include "io/dataset.hpp"
#include "io/euroc_reader.hpp"
#include "io/kestrel_sequence.hpp"
#include "io/tum_rgbd_reader.hpp"
#include "io/yaml_fields.hpp"
#include "tests/io/io_test_util.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

namespace fs = std::filesystem;
const fs::path kFrame = test::shared_data("tum_fr3/frame");

fs::path tum_folder(const std::string& name, const std::string& rgb_txt) {
  const fs::path dir = test::temp_dir(name) / "rgbd_dataset_freiburg3_bad";
  test::copy(kFrame / "rgb_1341846313.592026.png", dir / "rgb/1.000000.png");
  test::copy(kFrame / "rgb_1341846313.592026.png", dir / "rgb/2.000000.png");
  test::copy(kFrame / "depth_1341846313.592088.png", dir / "depth/1.000000.png");
  test::copy(kFrame / "depth_1341846313.592088.png", dir / "depth/2.000000.png");
  test::write_file(dir / "rgb.txt", rgb_txt);
  test::write_file(dir / "depth.txt",
                   "# depth\n1.000000 depth/1.000000.png\n2.000000 depth/2.000000.png\n");
  return dir;
}

void drain(MeasurementSource& src) {
  while (src.next()) {
  }
}

TEST(BadInput, MalformedLineInRgbTxt) {
  const fs::path dir =
      tum_folder("bad_rgb", "# rgb\n1.000000 rgb/1.000000.png\n2.0x00 rgb/2.000000.png\n");
  test::expect_error([&] { open_tum_rgbd(dir.string()); },
                     {(dir / "rgb.txt").string() + ":3", "timestamp", "2.0x00"});
  const fs::path dir2 = tum_folder("bad_rgb2", "# rgb\n1.000000\n");
  test::expect_error([&] { open_tum_rgbd(dir2.string()); },
                     {(dir2 / "rgb.txt").string() + ":2", "2 fields"});
}

TEST(BadInput, NonMonotonicRgbTxt) {
  const fs::path dir =
      tum_folder("mono_rgb", "2.000000 rgb/2.000000.png\n1.000000 rgb/1.000000.png\n");
  test::expect_error([&] { open_tum_rgbd(dir.string()); },
                     {(dir / "rgb.txt").string() + ":2", "not after the previous"});
}

TEST(BadInput, MissingImageFile) {
  const fs::path dir =
      tum_folder("missing_img", "1.000000 rgb/1.000000.png\n2.000000 rgb/2.000000.png\n");
  fs::remove(dir / "rgb/2.000000.png");
  auto src = open_tum_rgbd(dir.string());
  ASSERT_TRUE(src->next());  // frame 1 is fine; the error comes when frame 2 is reached
  test::expect_error([&] { src->next(); }, {(dir / "rgb.txt").string() + ":2",
                                            (dir / "rgb/2.000000.png").string(), "cannot open"});
}

TEST(BadInput, TruncatedPngInDataset) {
  const fs::path dir =
      tum_folder("trunc", "1.000000 rgb/1.000000.png\n2.000000 rgb/2.000000.png\n");
  const auto bytes = test::read_bytes(dir / "depth/2.000000.png");
  test::write_file(
      dir / "depth/2.000000.png",
      std::string(bytes.begin(), bytes.begin() + static_cast<long>(bytes.size() * 3 / 4)));
  auto src = open_tum_rgbd(dir.string());
  test::expect_error([&] { drain(*src); }, {(dir / "depth.txt").string() + ":3",
                                            (dir / "depth/2.000000.png").string(), "truncated"});
}

TEST(BadInput, DepthThatIsNot16Bit) {
  const fs::path dir = tum_folder("depth8", "1.000000 rgb/1.000000.png\n");
  test::copy(kFrame / "rgb_1341846313.592026.png", dir / "depth/1.000000.png");
  auto src = open_tum_rgbd(dir.string());
  test::expect_error([&] { drain(*src); },
                     {(dir / "depth.txt").string() + ":2", "depth/1.000000.png", "16-bit"});
}

fs::path asl_folder(const std::string& name, const std::string& imu_rows) {
  const fs::path src = test::shared_data("euroc/V1_01_micro/mav0");
  const fs::path mav = test::temp_dir(name) / "mav0";
  test::copy(src / "cam0/sensor.yaml", mav / "cam0/sensor.yaml");
  test::copy(src / "imu0/sensor.yaml", mav / "imu0/sensor.yaml");
  test::copy(src / "cam0/data/1403715273262142976.png", mav / "cam0/data/1403715273262142976.png");
  test::write_file(mav / "cam0/data.csv",
                   "#timestamp [ns],filename\n1403715273262142976,1403715273262142976.png\n");
  test::write_file(mav / "imu0/data.csv", "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n" + imu_rows);
  return mav.parent_path();
}

TEST(BadInput, NanInImuCsv) {
  const fs::path dir = asl_folder("imu_nan",
                                  "1403715273262142976,0.1,0.2,0.3,9.8,0.1,0.2\n"
                                  "1403715273267142912,0.1,nan,0.3,9.8,0.1,0.2\n");
  test::expect_error([&] { EurocReader r(dir.string()); },
                     {(dir / "mav0/imu0/data.csv").string() + ":3", "w_y", "finite"});
}

TEST(BadInput, NonMonotonicImuCsv) {
  const fs::path dir = asl_folder("imu_order",
                                  "1403715273262142976,0.1,0.2,0.3,9.8,0.1,0.2\n"
                                  "1403715273267142912,0.1,0.2,0.3,9.8,0.1,0.2\n"
                                  "1403715273267142912,0.1,0.2,0.3,9.8,0.1,0.2\n");
  test::expect_error([&] { EurocReader r(dir.string()); },
                     {(dir / "mav0/imu0/data.csv").string() + ":4", "timestamp", "not after"});
}

TEST(BadInput, MonocularAslWithoutCam1Works) {
  const fs::path dir = asl_folder("asl_mono", "1403715273262142976,0.1,0.2,0.3,9.8,0.1,0.2\n");
  EurocReader r(dir.string());
  EXPECT_FALSE(r.calibration().is_stereo());
  EXPECT_EQ(r.frame_count(), 1u);
}

TEST(BadInput, KestrelImuCsvAndBoxes) {
  const fs::path dir = test::temp_dir("kseq_bad") / "seq";
  { KestrelSequenceWriter w(dir.string(), Calibration{}); }
  test::write_file(dir / "imu.csv",
                   "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n10,1,2,3,4,5,6\n20,1,2,3,4,5\n");
  test::expect_error([&] { open_kestrel_sequence(dir.string()); },
                     {(dir / "imu.csv").string() + ":3", "7 fields"});
  test::write_file(dir / "boxes.csv", "#stamp,...\n1.0,3,person,1,2,3,4,maybe,0\n");
  test::expect_error([&] { read_boxes((dir / "boxes.csv").string()); },
                     {(dir / "boxes.csv").string() + ":2", "moving"});
}

// Found by fuzz/dataset_parsers_fuzz.cpp: a number too large for a double escaped as a
// nlohmann exception.
TEST(BadInput, ObjectsJsonWithANumberOutOfRange) {
  test::expect_error(
      [] {
        parse_objects_json(R"([{"id": 1, "label": "chair", "center": [1e999, 0, 0]}])",
                           "objects.json");
      },
      {"objects.json", "JSON"});
}

// Image sizes in calibration files are whole numbers in range: a width of 1e12 once reached an
// int cast, which is undefined.
TEST(BadInput, ImageSizeInAYamlFileIsAWholeNumberInRange) {
  const YamlFile y = YamlFile::parse("w: 640\nbig: 1e12\nhalf: 640.5\nzero: 0\n", "cam.yaml");
  EXPECT_EQ(y.whole(y.root()["w"], "w", 1, 65536), 640);
  for (const char* key : {"big", "half", "zero"}) {
    test::expect_error([&] { y.whole(y.root()[key], key, 1, 65536); },
                       {"cam.yaml:", key, "whole number in [1, 65536]"});
  }
}

}  // namespace
}  // namespace kestrel::io
