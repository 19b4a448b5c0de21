#pragma once
// A 3D occupancy map (liboctomap's OcTree behind a pointer, so its headers stay in the .cpp).
// Every scan is inserted as rays: voxels a ray passes through become more likely free, its end
// point more likely occupied. A walker who has gone is carved away by later rays through where
// it stood.
#include <memory>
#include <string>
#include <vector>

#include "core/eigen_types.hpp"
#include "maps/occupancy_grid.hpp"

namespace kestrel::maps {

struct BandColumns;  // maps/free_space_rule.hpp

struct OctreeOptions {
  double resolution = 0.10;  // metres, leaf voxel edge
  double max_range = 8.0;    // metres; longer rays carve free space up to here only
  double prob_hit = 0.7;
  double prob_miss = 0.4;
  double clamp_min = 0.12;
  double clamp_max = 0.97;
};

class OccupancyOctree {
 public:
  explicit OccupancyOctree(const OctreeOptions& options = {});
  ~OccupancyOctree();
  OccupancyOctree(OccupancyOctree&&) noexcept;
  OccupancyOctree& operator=(OccupancyOctree&&) noexcept;

  const OctreeOptions& options() const { return options_; }
  // One scan: end points in the world frame, all seen from `origin`.
  void insert_scan(const Vec3& origin, const std::vector<Eigen::Vector3f>& points_w);
  // The same, with free space carved along ray i only up to carve_ends_w[i] (a point on the
  // segment origin..points_w[i]): a ray that meets its surface at a grazing angle runs within a
  // voxel of it for a long way, and carving all of it clears the surface's own voxels.
  // Voxels holding an end point of this scan are never carved by it.
  void insert_scan(const Vec3& origin, const std::vector<Eigen::Vector3f>& points_w,
                   const std::vector<Eigen::Vector3f>& carve_ends_w);
  // Only free space along rays that hit nothing measurable (no end point is marked).
  void insert_free_rays(const Vec3& origin, const std::vector<Eigen::Vector3f>& ends_w);

  bool is_occupied(const Vec3& p) const;  // false for free and unknown
  bool is_known(const Vec3& p) const;
  // Leaf centres of every occupied voxel (pruned nodes expanded to leaf size).
  std::vector<Vec3> occupied_voxels() const;
  std::size_t leaf_count() const;

  // The 2D grid of a height band: a cell is occupied when an occupied voxel in [z_min, z_max]
  // lies above it, free when only free voxels of the band do and they fill the band's lowest
  // `free_clearance` metres (0: any free voxel will do), unknown otherwise.
  OccupancyGrid project(double z_min, double z_max, double free_clearance = 0.0) const;
  // The band's columns behind that rule: occupied, band-free or unknown per cell, and which of
  // the lowest free_clearance metres' voxel layers are seen free (maps/free_space_rule.hpp).
  BandColumns project_columns(double z_min, double z_max, double free_clearance) const;

  void write_binary(const std::string& path) const;  // .bt, octovis/octomap_server read it
  static OccupancyOctree read_binary(const std::string& path);

 private:
  struct Impl;
  OctreeOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::maps
