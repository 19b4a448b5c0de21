// apply_cell_updates must leave the tree exactly as OcTree::updateNode, key by key and not
// lazy, leaves it: values, pruning and inner nodes (every node is compared), over scans that
// saturate voxels, prune whole blocks and expand them again.
#include <gtest/gtest.h>

#include <octomap/OcTree.h>

#include <algorithm>
#include <random>
#include <sstream>
#include <vector>

#include "maps/octree_batch_update.hpp"
#include "maps/voxel_key_index.hpp"

using namespace kestrel::maps;

namespace {

// Every node, inner ones included, in the tree's own order: depth, key, log-odds, children.
std::string dump(const octomap::OcTree& t) {
  std::ostringstream out;
  for (auto it = t.begin_tree(), end = t.end_tree(); it != end; ++it) {
    const auto k = it.getKey();
    out << it.getDepth() << ' ' << k[0] << ' ' << k[1] << ' ' << k[2] << ' ' << it->getLogOdds()
        << ' ' << t.nodeHasChildren(&*it) << '\n';
  }
  return out.str();
}

}  // namespace

TEST(OctreeBatchUpdate, LeavesTheTreeAsKeyByKeyUpdatesDo) {
  octomap::OcTree by_key(0.1), batched(0.1);
  for (auto* t : {&by_key, &batched}) {
    t->setProbHit(0.7);
    t->setProbMiss(0.4);
    t->setClampingThresMin(0.12);
    t->setClampingThresMax(0.97);
  }
  std::mt19937 rng(11);
  // A 16^3 block aligned to the tree's lattice, so whole octants saturate and prune.
  std::uniform_int_distribution<int> coord(32768 - 8, 32768 + 7);
  int pruned_scans = 0;
  for (int scan = 0; scan < 60; ++scan) {
    // First scattered hits and misses; then sweeps of the whole block that are mostly free
    // space, so free octants saturate and prune, and a few hits expand them again.
    VoxelKeyIndex seen;
    std::vector<CellUpdate> updates;
    if (scan < 10) {
      std::bernoulli_distribution is_hit(0.5);
      for (int i = 0; i < 1500; ++i) {
        const auto k = VoxelKeyIndex::pack(static_cast<std::uint16_t>(coord(rng)),
                                           static_cast<std::uint16_t>(coord(rng)),
                                           static_cast<std::uint16_t>(coord(rng)));
        if (seen.insert(k).second) updates.push_back({k, is_hit(rng)});
      }
    } else {
      std::bernoulli_distribution is_hit(scan % 5 == 0 ? 0.01 : 0.0);
      std::bernoulli_distribution skip(0.3);
      for (int x = 32760; x < 32776; ++x)
        for (int y = 32760; y < 32776; ++y)
          for (int z = 32760; z < 32776; ++z) {
            if (skip(rng)) continue;
            updates.push_back(
                {VoxelKeyIndex::pack(static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y),
                                     static_cast<std::uint16_t>(z)),
                 is_hit(rng)});
          }
      std::shuffle(updates.begin(), updates.end(), rng);
    }
    for (const CellUpdate& u : updates)
      by_key.updateNode(octomap::OcTreeKey(static_cast<std::uint16_t>(u.key),
                                           static_cast<std::uint16_t>(u.key >> 16),
                                           static_cast<std::uint16_t>(u.key >> 32)),
                        u.hit, false);
    apply_cell_updates(batched, updates);
    ASSERT_EQ(by_key.size(), batched.size()) << "scan " << scan;
    ASSERT_EQ(dump(by_key), dump(batched)) << "scan " << scan;
    if (by_key.getNumLeafNodes() < 16u * 16u * 16u) ++pruned_scans;
  }
  // The scans did what the test is for: octants were pruned, and expanded again.
  EXPECT_GT(pruned_scans, 10);
  EXPECT_GT(by_key.getNumLeafNodes(), 8u);
}

TEST(OctreeBatchUpdate, AnEmptyTreeAndAnEmptyScan) {
  octomap::OcTree t(0.1);
  std::vector<CellUpdate> none;
  apply_cell_updates(t, none);
  EXPECT_EQ(t.size(), 0u);
  std::vector<CellUpdate> one = {{VoxelKeyIndex::pack(32768, 32768, 32768), true}};
  apply_cell_updates(t, one);
  ASSERT_NE(t.search(octomap::OcTreeKey(32768, 32768, 32768)), nullptr);
  EXPECT_TRUE(t.isNodeOccupied(t.search(octomap::OcTreeKey(32768, 32768, 32768))));
}
