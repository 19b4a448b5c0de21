#include "io/dataset_lists.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "tests/test_paths.hpp"

namespace kestrel::io {
namespace {

std::size_t count_data_lines(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] != '#') ++n;
  }
  return n;
}

TEST(DatasetLists, ParsesEveryFr3AssociationFile) {
  const auto dir = test::shared_data("tum_fr3/associations");
  int files = 0;
  for (const auto& f : std::filesystem::directory_iterator(dir)) {
    const auto entries = parse_association(TextTable::read(f.path().string()));
    ++files;
    ASSERT_EQ(entries.size(), count_data_lines(f.path())) << f.path();
    ASSERT_GT(entries.size(), 100u);
    for (const auto& e : entries) {
      // File names are the stamps; pairs are within associate.py's 0.02 s.
      EXPECT_EQ(e.color.path,
                "rgb/" + format_seconds(e.color.t).substr(0, format_seconds(e.color.t).size() - 3) +
                    ".png");
      EXPECT_LT(std::abs(e.color.t - e.depth.t), 20'000'000);
    }
    // Re-associating the listed stamps with associate.py's rule gives the same pairs.
    std::vector<Timestamp> a, b;
    for (const auto& e : entries) {
      a.push_back(e.color.t);
      b.push_back(e.depth.t);
    }
    const auto pairs = associate(a, b, 20'000'000);
    ASSERT_EQ(pairs.size(), entries.size()) << f.path();
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      EXPECT_EQ(pairs[k].first, k);
      EXPECT_EQ(pairs[k].second, k);
    }
  }
  EXPECT_EQ(files, 8);
  const auto xyz = parse_association(TextTable::read((dir / "fr3_walking_xyz.txt").string()));
  EXPECT_EQ(xyz.front().color.t, 1341846313592026000);
  EXPECT_EQ(xyz.front().depth.t, 1341846313592088000);
  EXPECT_EQ(xyz.front().depth.path, "depth/1341846313.592088.png");
}

TEST(Associate, GreedyBySmallestDifference) {
  // 100 is closest to 104 (diff 4) but 104 is taken first by 105 (diff 1); 100 gets 95 (diff 5).
  const std::vector<Timestamp> a = {100, 105, 300};
  const std::vector<Timestamp> b = {95, 104, 250};
  const auto m = associate(a, b, 10);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0], std::make_pair(std::size_t{0}, std::size_t{0}));
  EXPECT_EQ(m[1], std::make_pair(std::size_t{1}, std::size_t{1}));
}

TEST(Associate, MaxDifferenceIsStrict) {
  EXPECT_TRUE(associate({0}, {10}, 10).empty());
  EXPECT_EQ(associate({0}, {9}, 10).size(), 1u);
  EXPECT_EQ(associate({10}, {0}, 11).size(), 1u);
}

TEST(Associate, UnsortedInputAndTies) {
  // b[0] and b[1] are equally far from a[0]: the smaller b stamp wins, as in associate.py's
  // sort of (diff, a, b) tuples.
  const auto m = associate({50}, {60, 40}, 20);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].second, 1u);
}

TEST(DatasetLists, AslImuCsv) {
  const TextTable t = TextTable::parse(
      "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n"
      "1000,0.1,0.2,0.3,9.8,0,0\n"
      "2000,-1e-3,2,3,4,5,6\n",
      "imu.csv");
  const auto s = parse_asl_imu_csv(t);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[1].t, 2000);
  EXPECT_EQ(s[1].gyro.x(), -1e-3);
  EXPECT_EQ(s[0].acc.x(), 9.8);
}

}  // namespace
}  // namespace kestrel::io
