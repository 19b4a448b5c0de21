#pragma once
// A voxel-downsampled coloured, labelled point cloud: every voxel keeps the mean position and
// colour of the points that fell in it and the label most of them carried (Boyer-Moore vote,
// so a voxel costs a few bytes whatever the number of votes). Voxels are kept in the order they
// were first seen, and points() returns them so.
#include <cstdint>
#include <vector>

#include "core/eigen_types.hpp"
#include "maps/voxel_key_index.hpp"

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
  std::size_t size() const { return accums_.size(); }
  void clear() {
    index_.clear();
    accums_.clear();
  }

  void add(const Eigen::Vector3f& p, std::uint8_t r, std::uint8_t g, std::uint8_t b,
           std::uint16_t label);
  // Drops the voxels whose mean point fails keep(point): what the OctoMap has since carved as
  // free space leaves the cloud too.
  template <typename Keep>
  void filter(Keep keep) {
    std::vector<bool> kept(accums_.size());
    std::size_t n = 0;
    for (std::size_t i = 0; i < accums_.size(); ++i)
      if ((kept[i] = keep(mean(accums_[i])))) accums_[n++] = accums_[i];
    accums_.resize(n);
    index_.compact(kept);
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
  VoxelKeyIndex index_;  // voxel key -> position in accums_
  std::vector<Accum> accums_;
};

}  // namespace kestrel::maps
