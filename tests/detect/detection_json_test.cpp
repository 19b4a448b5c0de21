#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.hpp"
#include "detect/detection_json.hpp"
#include "detect/draw_detections.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::detect {
namespace {

TEST(DetectionJson, RoundTripsTheFields) {
  LabelledDetectionSet s;
  s.source = "a.png";
  s.set.t = 1'500'000'000;
  s.set.latency_ms = 9.5;
  Detection d;
  d.label = "person";
  d.class_id = 0;
  d.score = 0.75f;
  d.x_min = 1;
  d.y_min = 2;
  d.x_max = 30;
  d.y_max = 40;
  s.set.boxes.push_back(d);
  const auto j = nlohmann::json::parse(detections_to_json({s}));
  ASSERT_EQ(j.size(), 1u);
  EXPECT_EQ(j[0]["source"], "a.png");
  EXPECT_DOUBLE_EQ(j[0]["t"].get<double>(), 1.5);
  EXPECT_DOUBLE_EQ(j[0]["latency_ms"].get<double>(), 9.5);
  ASSERT_EQ(j[0]["boxes"].size(), 1u);
  EXPECT_EQ(j[0]["boxes"][0]["label"], "person");
  EXPECT_EQ(j[0]["boxes"][0]["class_id"], 0);
  EXPECT_FLOAT_EQ(j[0]["boxes"][0]["score"].get<float>(), 0.75f);
  EXPECT_FLOAT_EQ(j[0]["boxes"][0]["y_max"].get<float>(), 40.0f);

  const auto dir = test::temp_dir("detection_json");
  const std::string path = (dir / "out.json").string();
  write_detections_json(path, {s});
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), detections_to_json({s}));
  const std::string bad = (dir / "no/such/dir/out.json").string();
  try {
    write_detections_json(bad, {s});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos);
  }
}

TEST(DrawDetections, OutlinesTheBoxInColour) {
  Image grey = Image::allocate(64, 48, 1, PixelType::kU8);
  std::fill(grey.data->begin(), grey.data->end(), std::uint8_t{100});
  Detection person;
  person.label = "person";
  person.score = 0.9f;
  person.x_min = 10;
  person.y_min = 20;
  person.x_max = 40;
  person.y_max = 45;
  const Image out = draw_detections(grey, {person});
  ASSERT_EQ(out.channels, 3);
  ASSERT_EQ(out.width, 64);
  // The bottom-left corner of the box is red (a dynamic class); the centre is untouched grey.
  const std::uint8_t* corner = out.row<std::uint8_t>(44) + 3 * 10;
  EXPECT_EQ(corner[2], 255);
  EXPECT_EQ(corner[1], 0);
  const std::uint8_t* centre = out.row<std::uint8_t>(35) + 3 * 25;
  EXPECT_EQ(centre[0], 100);
  EXPECT_EQ(centre[2], 100);
  // The input is not modified.
  EXPECT_EQ(grey.row<std::uint8_t>(44)[10], 100);
}

}  // namespace
}  // namespace kestrel::detect
