#include "maps/voxel_cloud.hpp"

#include <cmath>

namespace kestrel::maps {

std::uint64_t VoxelCloud::key(const Eigen::Vector3f& p) const {
  // 21 bits per axis around the origin: +-1 048 576 voxels, kilometres at centimetre voxels.
  auto q = [&](float v) {
    const auto i = static_cast<std::int64_t>(std::floor(v / voxel_)) + (1 << 20);
    return static_cast<std::uint64_t>(i) & 0x1FFFFF;
  };
  return q(p.x()) | (q(p.y()) << 21) | (q(p.z()) << 42);
}

void VoxelCloud::add(const Eigen::Vector3f& p, std::uint8_t r, std::uint8_t g, std::uint8_t b,
                     std::uint16_t label) {
  const auto [i, fresh] = index_.insert(key(p));
  if (fresh) accums_.emplace_back();
  Accum& a = accums_[i];
  a.sx += p.x();
  a.sy += p.y();
  a.sz += p.z();
  a.sr += r;
  a.sg += g;
  a.sb += b;
  ++a.n;
  if (a.votes == 0) {
    a.label = label;
    a.votes = 1;
  } else {
    a.votes += a.label == label ? 1 : -1;
  }
}

std::vector<CloudPoint> VoxelCloud::points() const {
  std::vector<CloudPoint> out;
  out.reserve(accums_.size());
  for (const Accum& a : accums_) {
    CloudPoint c;
    c.p = mean(a);
    c.r = static_cast<std::uint8_t>(a.sr / a.n);
    c.g = static_cast<std::uint8_t>(a.sg / a.n);
    c.b = static_cast<std::uint8_t>(a.sb / a.n);
    c.label = a.label;
    out.push_back(c);
  }
  return out;
}

}  // namespace kestrel::maps
