#include "maps/octree_batch_update.hpp"

#include <octomap/OcTree.h>

#include <array>
#include <cstddef>

namespace kestrel::maps {
namespace {

using octomap::OcTree;
using octomap::OcTreeNode;

octomap::OcTreeKey unpack(std::uint64_t p) {
  return octomap::OcTreeKey(static_cast<std::uint16_t>(p), static_cast<std::uint16_t>(p >> 16),
                            static_cast<std::uint16_t>(p >> 32));
}

// The key's bits interleaved (x, y, z from the lowest bit up): at each level of the tree the
// child index is the next three bits (OcTree's computeChildIdx), and the walk reads one word
// per update. The highest bit carries hit or miss.
std::uint64_t spread(std::uint64_t v) {  // 16 bits to every third of 48
  v &= 0xFFFF;
  v = (v | v << 16) & 0x0000FF0000FFull;
  v = (v | v << 8) & 0x00F00F00F00Full;
  v = (v | v << 4) & 0x0C30C30C30C3ull;
  v = (v | v << 2) & 0x249249249249ull;
  return v;
}

constexpr std::uint64_t kHit = std::uint64_t{1} << 63;

std::uint64_t morton(const CellUpdate& u) {
  return spread(u.key) | spread(u.key >> 16) << 1 | spread(u.key >> 32) << 2 | (u.hit ? kHit : 0);
}

unsigned child_index(std::uint64_t m, unsigned level_bit) {
  return static_cast<unsigned>(m >> (3 * level_bit)) & 7u;
}

struct Walk {
  OcTree& tree;
  float hit_log, miss_log, clamp_min_log, clamp_max_log;
  unsigned depth_max;

  // updateNode's early abort, for speed only: an update towards the clamp a node already sits
  // at changes nothing, so a pruned node need not be expanded for it (it would be pruned
  // again) nor a leaf touched.
  bool saturated(const OcTreeNode* n, bool hit) const {
    return hit ? n->getLogOdds() >= clamp_max_log : n->getLogOdds() <= clamp_min_log;
  }

  // Updates (morton) in [src, src + n) all lie below `node`, at `depth`. `dst` is scratch of n.
  void apply(OcTreeNode* node, bool just_created, unsigned depth, std::uint64_t* src, std::size_t n,
             std::uint64_t* dst) {
    if (depth == depth_max) {  // a leaf: exactly one update (the keys are distinct)
      const bool hit = (*src & kHit) != 0;
      if (just_created || !saturated(node, hit))
        tree.updateNodeLogOdds(node, hit ? hit_log : miss_log);
      return;
    }
    if (!just_created && !tree.nodeHasChildren(node)) {
      // A pruned node: its value stands for every leaf below it.
      std::size_t kept = 0;
      for (std::size_t i = 0; i < n; ++i)
        if (!saturated(node, (src[i] & kHit) != 0)) src[kept++] = src[i];
      if (kept == 0) return;
      n = kept;
      tree.expandNode(node);
    }
    const unsigned bit = depth_max - 1 - depth;
    if (n == 1) {  // most of the walk near the leaves: one key, no split
      descend(node, child_index(*src, bit), depth, src, 1, dst);
      if (!tree.pruneNode(node)) node->updateOccupancyChildren();
      return;
    }
    std::array<std::size_t, 9> start{};
    for (std::size_t i = 0; i < n; ++i) ++start[child_index(src[i], bit) + 1];
    for (int c = 0; c < 8; ++c) start[c + 1] += start[c];
    std::array<std::size_t, 8> fill{};
    for (int c = 0; c < 8; ++c) fill[c] = start[c];
    for (std::size_t i = 0; i < n; ++i) dst[fill[child_index(src[i], bit)]++] = src[i];
    for (unsigned c = 0; c < 8; ++c)
      if (start[c + 1] > start[c])
        descend(node, c, depth, dst + start[c], start[c + 1] - start[c], src + start[c]);
    if (!tree.pruneNode(node)) node->updateOccupancyChildren();
  }

  void descend(OcTreeNode* node, unsigned c, unsigned depth, std::uint64_t* src, std::size_t n,
               std::uint64_t* dst) {
    bool created = false;
    if (!tree.nodeChildExists(node, c)) {
      tree.createNodeChild(node, c);
      created = true;
    }
    apply(tree.getNodeChild(node, c), created, depth + 1, src, n, dst);
  }
};

}  // namespace

void apply_cell_updates(OcTree& tree, const std::vector<CellUpdate>& updates) {
  if (updates.empty()) return;
  std::size_t first = 0;
  if (!tree.getRoot()) {
    // Only updateNode can create the root.
    tree.updateNode(unpack(updates[0].key), updates[0].hit, false);
    first = 1;
  }
  if (first == updates.size()) return;
  Walk w{tree,
         tree.getProbHitLog(),
         tree.getProbMissLog(),
         tree.getClampingThresMinLog(),
         tree.getClampingThresMaxLog(),
         tree.getTreeDepth()};
  std::vector<std::uint64_t> codes(updates.size() - first), scratch(codes.size());
  for (std::size_t i = first; i < updates.size(); ++i) codes[i - first] = morton(updates[i]);
  w.apply(tree.getRoot(), false, 0, codes.data(), codes.size(), scratch.data());
}

}  // namespace kestrel::maps
