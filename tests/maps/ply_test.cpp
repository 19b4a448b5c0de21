#include <gtest/gtest.h>

#include <fstream>

#include "core/error.hpp"
#include "maps/ply_writer.hpp"
#include "tests/test_paths.hpp"

using namespace kestrel;
using namespace kestrel::maps;

TEST(Ply, HeaderIsBinaryWithColourAndLabelAndRoundTrips) {
  const auto dir = test::temp_dir("maps-ply");
  std::vector<CloudPoint> pts(3);
  pts[0].p = {1.5f, -2.25f, 0.125f};
  pts[0].r = 255;
  pts[0].g = 1;
  pts[0].b = 128;
  pts[0].label = 57;
  pts[2].label = 65535;
  const std::string path = (dir / "c.ply").string();
  write_ply(path, pts);
  std::ifstream in(path, std::ios::binary);
  std::string header, line;
  while (std::getline(in, line) && line != "end_header") header += line + "\n";
  EXPECT_EQ(header.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(header.find("element vertex 3\n"), std::string::npos);
  EXPECT_NE(header.find("property uchar red\nproperty uchar green\nproperty uchar blue\n"),
            std::string::npos);
  EXPECT_NE(header.find("property ushort label\n"), std::string::npos);
  EXPECT_EQ(std::filesystem::file_size(path), header.size() + 11 + 3 * 17);
  const auto back = read_ply(path);
  ASSERT_EQ(back.size(), 3u);
  EXPECT_EQ(back[0].p, pts[0].p);
  EXPECT_EQ(back[0].r, 255);
  EXPECT_EQ(back[0].g, 1);
  EXPECT_EQ(back[0].b, 128);
  EXPECT_EQ(back[0].label, 57);
  EXPECT_EQ(back[2].label, 65535);
}

TEST(Ply, ReaderNamesTheBadHeaderLine) {
  const auto dir = test::temp_dir("maps-ply-bad");
  const std::string path = (dir / "b.ply").string();
  std::ofstream(path) << "ply\nformat ascii 1.0\nelement vertex 1\n";
  try {
    read_ply(path);
    FAIL() << "accepted an ASCII PLY";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("b.ply:2: field 'format'"), std::string::npos) << e.what();
  }
}
