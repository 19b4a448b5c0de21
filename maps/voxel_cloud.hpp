#pragma once
// A voxel-downsampled coloured, labelled point cloud: every voxel keeps the mean position and
// colour of the points that fell in it and the label most of them carried (Boyer-Moore vote,
// so a voxel costs a few bytes whatever the number of votes).
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/eigen_types.hpp"

namespace kestrel::maps {

struct CloudPoint {
  Eigen::Vector3f p = Eigen::Vector3f::Zero();  // world frame, metres
  std::uint8_t r = 0, g = 0, b = 0;
  std::uint16_t label = 0;  // 0 = none, else COCO class id + 1
};

class VoxelCloud {
 public:
  explicit VoxelCloud(double voxel_size = 0.03) : voxel_(voxel_size) {}

  double voxel_size() const { return voxel_; }
  std::size_t size() const { return voxels_.size(); }
  void clear() { voxels_.clear(); }

  void add(const Eigen::Vector3f& p, std::uint8_t r, std::uint8_t g, std::uint8_t b,
           std::uint16_t label);
  // Drops the voxels whose mean point fails keep(point): what the OctoMap has since carved as
  // free space leaves the cloud too.
  template <typename Keep>
  void filter(Keep keep) {
    for (auto it = voxels_.begin(); it != voxels_.end();) {
      if (!keep(mean(it->second)))
        it = voxels_.erase(it);
      else
        ++it;
    }
  }
  std::vector<CloudPoint> points() const;

 private:
  struct Accum {
    float sx = 0, sy = 0, sz = 0;
    std::uint32_t sr = 0, sg = 0, sb = 0;
    std::uint32_t n = 0;
    std::uint16_t label = 0;
    std::int32_t votes = 0;
  };
  static Eigen::Vector3f mean(const Accum& a) {
    return Eigen::Vector3f(a.sx, a.sy, a.sz) / static_cast<float>(a.n);
  }
  std::uint64_t key(const Eigen::Vector3f& p) const;

  double voxel_;
  std::unordered_map<std::uint64_t, Accum> voxels_;
};

}  // namespace kestrel::maps
