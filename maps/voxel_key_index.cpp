#include "maps/voxel_key_index.hpp"

#include <algorithm>

namespace kestrel::maps {

std::size_t VoxelKeyIndex::home(std::uint64_t key) const {
  // Fibonacci hashing: neighbouring voxels (keys differing in the low bits of one coordinate)
  // spread over the table.
  return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
}

std::pair<std::size_t, bool> VoxelKeyIndex::insert(std::uint64_t key) {
  if (2 * (keys_.size() + 1) > slots_.size())
    rehash(std::max<std::size_t>(slots_.size() * 2, std::size_t{1} << 12));
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t s = home(key);; s = (s + 1) & mask) {
    Slot& slot = slots_[s];
    if (slot.index == 0) {
      keys_.push_back(key);
      slot.key = key;
      slot.index = static_cast<std::uint32_t>(keys_.size());
      return {keys_.size() - 1, true};
    }
    if (slot.key == key) return {slot.index - 1, false};
  }
}

std::size_t VoxelKeyIndex::find(std::uint64_t key) const {
  if (keys_.empty()) return npos;
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t s = home(key);; s = (s + 1) & mask) {
    const Slot& slot = slots_[s];
    if (slot.index == 0) return npos;
    if (slot.key == key) return slot.index - 1;
  }
}

void VoxelKeyIndex::clear() {
  if (keys_.size() * 8 >= slots_.size()) {
    std::fill(slots_.begin(), slots_.end(), Slot{});
  } else {
    // Few keys in a large table: find every key's slot first; emptying slots as we go would
    // cut the probe chains of the keys not yet found.
    std::vector<std::size_t> at;
    at.reserve(keys_.size());
    const std::size_t mask = slots_.size() - 1;
    for (const std::uint64_t k : keys_) {
      std::size_t s = home(k);
      while (slots_[s].key != k || slots_[s].index == 0) s = (s + 1) & mask;
      at.push_back(s);
    }
    for (const std::size_t s : at) slots_[s] = Slot{};
  }
  keys_.clear();
}

void VoxelKeyIndex::compact(const std::vector<bool>& keep) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < keys_.size(); ++i)
    if (i < keep.size() && keep[i]) keys_[n++] = keys_[i];
  keys_.resize(n);
  rehash(slots_.size());
}

void VoxelKeyIndex::rehash(std::size_t capacity) {
  slots_.assign(capacity, Slot{});
  shift_ = 64;
  for (std::size_t c = capacity; c > 1; c >>= 1) --shift_;
  const std::size_t mask = capacity - 1;
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    std::size_t s = home(keys_[i]);
    while (slots_[s].index != 0) s = (s + 1) & mask;
    slots_[s] = Slot{keys_[i], static_cast<std::uint32_t>(i + 1)};
  }
}

}  // namespace kestrel::maps
