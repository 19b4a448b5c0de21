#include <gtest/gtest.h>

#include <fstream>

#include "core/error.hpp"
#include "maps/grid_io.hpp"
#include "tests/test_paths.hpp"

using namespace kestrel;
using namespace kestrel::maps;

namespace {

void write_text(const std::filesystem::path& p, const std::string& s) { std::ofstream(p) << s; }

std::string error_of(const std::string& yaml) {
  try {
    read_map(yaml);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MapIo, RoundTripKeepsCellsAndGeometry) {
  const auto dir = test::temp_dir("nav-roundtrip");
  OccupancyGrid g(7, 5, 0.05, Vec2(-1.25, 0.5), kFree);
  g.set({0, 0}, kOccupied);  // bottom-left
  g.set({6, 4}, kOccupied);  // top-right
  g.set({3, 2}, kUnknown);
  write_map((dir / "map.yaml").string(), g);
  ASSERT_TRUE(std::filesystem::exists(dir / "map.pgm"));
  const OccupancyGrid r = read_map((dir / "map.yaml").string());
  EXPECT_EQ(r.width(), 7);
  EXPECT_EQ(r.height(), 5);
  EXPECT_DOUBLE_EQ(r.resolution(), 0.05);
  EXPECT_DOUBLE_EQ(r.origin().x(), -1.25);
  EXPECT_DOUBLE_EQ(r.origin().y(), 0.5);
  EXPECT_EQ(r.cells(), g.cells());
  // In the image the top-right cell is in the first row: ROS flips rows.
  std::ifstream pgm(dir / "map.pgm", std::ios::binary);
  std::string magic, comment;
  std::getline(pgm, magic);
  EXPECT_EQ(magic, "P5");
}

TEST(MapIo, ReadsAsciiPgmWithNegate) {
  const auto dir = test::temp_dir("nav-ascii");
  write_text(dir / "m.pgm", "P2\n# c\n2 1\n255\n0 255\n");
  write_text(dir / "m.yaml", "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\n");
  const OccupancyGrid r = read_map((dir / "m.yaml").string());
  EXPECT_EQ(r.at({0, 0}), kFree);  // negate: black is free
  EXPECT_EQ(r.at({1, 0}), kOccupied);
}

TEST(MapIo, ErrorsNameFileLineAndField) {
  const auto dir = test::temp_dir("nav-errors");
  write_text(dir / "m.pgm", "P5\n2 1\n255\nab");
  const std::string y = (dir / "m.yaml").string();
  write_text(y, "image: m.pgm\nresolution: 0.1\n");
  EXPECT_NE(error_of(y).find("field 'origin'"), std::string::npos) << error_of(y);
  write_text(y, "image: m.pgm\nresolution: abc\norigin: [0, 0, 0]\n");
  EXPECT_NE(error_of(y).find(":2: field 'resolution'"), std::string::npos) << error_of(y);
  write_text(y, "image: m.pgm\nresolution: 0.1\norigin: [0, 0]\n");
  EXPECT_NE(error_of(y).find("field 'origin'"), std::string::npos) << error_of(y);
  write_text(y, "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.9\n");
  EXPECT_NE(error_of(y).find("field 'free_thresh'"), std::string::npos) << error_of(y);
  write_text(y, "image: missing.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n");
  EXPECT_NE(error_of(y).find("missing.pgm"), std::string::npos) << error_of(y);
  write_text(dir / "bad.pgm", "P5\n2 x\n255\nab");
  write_text(y, "image: bad.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n");
  EXPECT_NE(error_of(y).find("bad.pgm:2: field 'height'"), std::string::npos) << error_of(y);
  write_text(dir / "short.pgm", "P5\n2 2\n255\nab");
  write_text(y, "image: short.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n");
  EXPECT_NE(error_of(y).find("field 'pixels'"), std::string::npos) << error_of(y);
}
