#pragma once
// The distinct cells one scan's rays pass through. A ray's cells are neighbours, and so are
// those of the rays beside it: a bit per cell of the cube the scan can reach (its range around
// the origin) finds repeats in memory already at hand, where a hash table spreads them over
// megabytes (uav-zigzag: ~400k ray cells a scan; hashed, their lookups were a third of the
// update).
// Cells outside the cube (none, when the cube covers the range) go to a hash index.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "maps/voxel_key_index.hpp"

namespace kestrel::maps {

class ScanCellSet {
 public:
  // Empties the set; its cube spans `half` cells either side of `centre` (packed keys,
  // VoxelKeyIndex::pack).
  void reset(std::uint64_t centre, int half);
  bool insert(std::uint64_t key);  // true when new
  std::size_t size() const { return keys_.size(); }
  std::uint64_t key(std::size_t i) const { return keys_[i]; }

 private:
  std::vector<std::uint64_t> bits_;
  std::vector<std::uint64_t> keys_;  // in insertion order
  VoxelKeyIndex outside_;
  int x0_ = 0, y0_ = 0, z0_ = 0, side_ = 0;
};

}  // namespace kestrel::maps
