#pragma once
// Voxel keys numbered densely in the order they were first seen: open addressing (linear
// probing) over one table. std::unordered_set / map allocate a node per key: while
// octomap::KeySet held a scan's cells (uav-zigzag: ~400k ray cells, ~150k distinct, a scan),
// the allocator took a third of a keyframe's map update. Holds a scan's end voxels and the
// dense cloud's voxels; the cloud's file then lists them in the order surfaces were first
// seen, whatever the hashing.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace kestrel::maps {

class VoxelKeyIndex {
 public:
  static constexpr std::size_t npos = static_cast<std::size_t>(-1);

  // Three 16-bit OctoMap key coordinates in one key.
  static std::uint64_t pack(std::uint16_t x, std::uint16_t y, std::uint16_t z) {
    return std::uint64_t{x} | std::uint64_t{y} << 16 | std::uint64_t{z} << 32;
  }

  // The key's index, and whether it was new (then the index is size() - 1).
  std::pair<std::size_t, bool> insert(std::uint64_t key);
  std::size_t find(std::uint64_t key) const;  // npos when absent
  bool contains(std::uint64_t key) const { return find(key) != npos; }
  std::size_t size() const { return keys_.size(); }
  bool empty() const { return keys_.empty(); }
  std::uint64_t key(std::size_t i) const { return keys_[i]; }
  // Empties the index and keeps its table.
  void clear();
  // Keeps the keys whose keep[i] is true, renumbered in their order.
  void compact(const std::vector<bool>& keep);

 private:
  struct Slot {
    std::uint64_t key = 0;
    std::uint32_t index = 0;  // + 1; 0 is empty
  };
  std::size_t home(std::uint64_t key) const;
  void rehash(std::size_t capacity);

  std::vector<Slot> slots_;
  std::vector<std::uint64_t> keys_;
  int shift_ = 64;
};

}  // namespace kestrel::maps
