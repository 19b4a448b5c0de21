#include "maps/scan_cell_set.hpp"

#include <algorithm>

namespace kestrel::maps {

namespace {

int coord(std::uint64_t key, int axis) { return static_cast<int>(key >> (16 * axis) & 0xFFFF); }

}  // namespace

void ScanCellSet::reset(std::uint64_t centre, int half) {
  const int side = 2 * half + 1;
  const std::size_t words =
      (static_cast<std::size_t>(side) * static_cast<std::size_t>(side) * side + 63) / 64;
  if (side != side_ || bits_.size() != words) {
    side_ = side;
    bits_.assign(words, 0);
  } else if (keys_.size() * 4 >= words) {
    std::fill(bits_.begin(), bits_.end(), 0);
  } else {
    // Few cells set: clear them one by one, at the cube they were set in.
    for (const std::uint64_t k : keys_) {
      const int dx = coord(k, 0) - x0_, dy = coord(k, 1) - y0_, dz = coord(k, 2) - z0_;
      if (dx < 0 || dy < 0 || dz < 0 || dx >= side_ || dy >= side_ || dz >= side_) continue;
      const std::size_t i = (static_cast<std::size_t>(dz) * side_ + dy) * side_ + dx;
      bits_[i >> 6] = 0;
    }
  }
  x0_ = coord(centre, 0) - half;
  y0_ = coord(centre, 1) - half;
  z0_ = coord(centre, 2) - half;
  keys_.clear();
  outside_.clear();
}

bool ScanCellSet::insert(std::uint64_t key) {
  const int dx = coord(key, 0) - x0_, dy = coord(key, 1) - y0_, dz = coord(key, 2) - z0_;
  if (dx < 0 || dy < 0 || dz < 0 || dx >= side_ || dy >= side_ || dz >= side_) {
    if (!outside_.insert(key).second) return false;
  } else {
    const std::size_t i = (static_cast<std::size_t>(dz) * side_ + dy) * side_ + dx;
    const std::uint64_t bit = std::uint64_t{1} << (i & 63);
    if (bits_[i >> 6] & bit) return false;
    bits_[i >> 6] |= bit;
  }
  keys_.push_back(key);
  return true;
}

}  // namespace kestrel::maps
