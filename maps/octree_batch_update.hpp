#pragma once
// One scan's occupancy updates applied to an OcTree in one walk. OcTree::updateNode descends
// from the root for every key, searches it once more for its early abort, and re-evaluates and
// tries to prune all 16 ancestors after each key: on uav-zigzag's scans (~150k distinct cells)
// that was more than half of the map update once the scan's cell sets stopped allocating. Here the
// keys are split by child at each level and every touched node is visited once; leaves, pruning and
// inner values end as the key-by-key non-lazy updates leave them
// (tests/maps/octree_batch_update_test.cpp compares the trees).
#include <cstdint>
#include <vector>

namespace octomap {
class OcTree;
}

namespace kestrel::maps {

struct CellUpdate {
  std::uint64_t key = 0;  // VoxelKeyIndex::pack of the leaf's key
  bool hit = false;       // occupied (prob_hit) or free (prob_miss)
};

// Each key at most once.
void apply_cell_updates(octomap::OcTree& tree, const std::vector<CellUpdate>& updates);

}  // namespace kestrel::maps
