#include <gtest/gtest.h>

#include <random>
#include <set>

#include "maps/scan_cell_set.hpp"

using kestrel::maps::ScanCellSet;
using kestrel::maps::VoxelKeyIndex;

namespace {

std::uint64_t key(int x, int y, int z) {
  return VoxelKeyIndex::pack(static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y),
                             static_cast<std::uint16_t>(z));
}

}  // namespace

// Scans from moving origins, some cells outside the cube (they go to the hash index), sets of
// many and of few cells (the two ways a reset clears the bits).
TEST(ScanCellSet, FindsRepeatsInsideAndOutsideItsCubeScanAfterScan) {
  ScanCellSet s;
  std::mt19937 rng(3);
  for (int scan = 0; scan < 8; ++scan) {
    const int cx = 32768 + 5 * scan, cy = 32768 - 3 * scan, cz = 32768;
    s.reset(key(cx, cy, cz), 10);
    std::uniform_int_distribution<int> d(-13, 13);  // a few cells past the cube's 10
    std::set<std::uint64_t> truth;
    const int n = scan % 2 ? 20 : 5000;
    for (int i = 0; i < n; ++i) {
      const auto k = key(cx + d(rng), cy + d(rng), cz + d(rng));
      ASSERT_EQ(s.insert(k), truth.insert(k).second) << "scan " << scan << " cell " << i;
    }
    ASSERT_EQ(s.size(), truth.size());
    std::set<std::uint64_t> listed;
    for (std::size_t i = 0; i < s.size(); ++i) listed.insert(s.key(i));
    EXPECT_EQ(listed, truth);
  }
}
