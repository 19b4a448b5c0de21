#include <gtest/gtest.h>

#include <map>
#include <random>
#include <vector>

#include "maps/voxel_key_index.hpp"

using kestrel::maps::VoxelKeyIndex;

TEST(VoxelKeyIndex, NumbersDistinctKeysInInsertionOrderThroughGrowthAndClear) {
  VoxelKeyIndex s;
  EXPECT_FALSE(s.contains(0));
  std::mt19937 rng(7);
  // Keys near each other, as along rays: many repeats, neighbours differing in low bits.
  std::uniform_int_distribution<int> coord(32760, 32800);
  for (int round = 0; round < 3; ++round) {
    std::map<std::uint64_t, std::size_t> truth;
    // Few keys in a grown table (round 1) clear slot by slot; many clear the whole table.
    const int n = round == 1 ? 300 : 40000;
    for (int i = 0; i < n; ++i) {
      const auto k = VoxelKeyIndex::pack(static_cast<std::uint16_t>(coord(rng)),
                                         static_cast<std::uint16_t>(coord(rng)),
                                         static_cast<std::uint16_t>(coord(rng)));
      const auto [it, fresh] = truth.emplace(k, truth.size());
      const auto [index, inserted] = s.insert(k);
      ASSERT_EQ(inserted, fresh);
      ASSERT_EQ(index, it->second);
    }
    ASSERT_EQ(s.size(), truth.size());
    for (const auto& [k, i] : truth) {
      ASSERT_EQ(s.key(i), k);
      ASSERT_EQ(s.find(k), i);
    }
    EXPECT_EQ(s.find(VoxelKeyIndex::pack(0, 0, 0)), VoxelKeyIndex::npos);
    s.clear();
    EXPECT_TRUE(s.empty());
    for (const auto& [k, i] : truth) ASSERT_FALSE(s.contains(k));
  }
}

TEST(VoxelKeyIndex, CompactKeepsTheChosenKeysInOrder) {
  VoxelKeyIndex s;
  for (std::uint64_t k = 100; k < 110; ++k) s.insert(k);
  std::vector<bool> keep(10, false);
  keep[1] = keep[4] = keep[9] = true;
  s.compact(keep);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s.key(0), 101u);
  EXPECT_EQ(s.key(1), 104u);
  EXPECT_EQ(s.key(2), 109u);
  EXPECT_EQ(s.find(104), 1u);
  EXPECT_FALSE(s.contains(100));
  EXPECT_EQ(s.insert(100), std::make_pair(std::size_t{3}, true));
}

TEST(VoxelKeyIndex, PackKeepsEachCoordinate) {
  const auto k = VoxelKeyIndex::pack(1, 65535, 32768);
  EXPECT_EQ(k & 0xFFFF, 1u);
  EXPECT_EQ(k >> 16 & 0xFFFF, 65535u);
  EXPECT_EQ(k >> 32, 32768u);
}
