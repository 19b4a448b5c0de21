#pragma once
// Builds the clean maps from keyframes (DESIGN.md maps/): a voxel-downsampled coloured and
// labelled cloud, an OctoMap with free-space carving and the 2D grid of a height band, from
// static pixels only. One call per keyframe from the mapping thread; no threads here.
#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/se3.hpp"
#include "maps/occupancy_grid.hpp"
#include "maps/occupancy_octree.hpp"
#include "maps/voxel_cloud.hpp"

namespace kestrel::maps {

struct MapBuilderOptions {
  double cloud_voxel = 0.03;    // metres
  int cloud_stride = 4;         // use every n-th pixel in x and y for the cloud
  int octree_stride = 8;        // ... and for the OctoMap rays (80x60 at VGA: the time budget)
  double min_depth = 0.3;       // metres; nearer readings are ignored
  double max_depth = 7.0;       // metres; farther readings only carve free space
  double far_ray_margin = 0.5;  // metres short of such a far reading
  OctreeOptions octree;
  double grid_z_min = 0.10;  // height band (world z, metres) projected into the 2D grid:
  double grid_z_max = 1.60;  // above the floor, up to what a ground robot can hit
};

struct MapKeyframe {
  SE3 T_w_c;
  const Image* color = nullptr;  // BGR 8-bit (3 channels) or grey; may be null (grey points)
  const Image* depth = nullptr;  // 16-bit, depth_scale units per metre
  double depth_scale = 5000.0;
  PinholeCamera camera;
  // Per pixel (row-major, width*height): non-zero = static. Null: every pixel is static.
  const std::vector<std::uint8_t>* static_mask = nullptr;
  // Per pixel: 0 = no label, else COCO class id + 1. Null: no labels.
  const std::vector<std::uint16_t>* labels = nullptr;
};

struct MapBoxRegion {  // a pixel box (max exclusive), e.g. a moving detection
  int x_min = 0, y_min = 0, x_max = 0, y_max = 0;
};

// width*height mask, 1 everywhere except inside the boxes (grown by `margin` pixels).
std::vector<std::uint8_t> static_mask_from_boxes(int width, int height,
                                                 const std::vector<MapBoxRegion>& boxes,
                                                 int margin = 4);

class MapBuilder {
 public:
  explicit MapBuilder(const MapBuilderOptions& options = {});

  // Adds one keyframe. Returns the number of static points used for the OctoMap.
  std::size_t insert(const MapKeyframe& kf);

  const MapBuilderOptions& options() const { return options_; }
  const OccupancyOctree& octree() const { return octree_; }
  const VoxelCloud& cloud() const { return cloud_; }
  // Cloud points whose voxel the OctoMap still holds occupied or has never seen: points of a
  // mover that was not masked are dropped once later rays have carved through them.
  std::vector<CloudPoint> clean_cloud() const;
  OccupancyGrid grid() const;

  // DIR/cloud.ply, DIR/octomap.bt, DIR/map.pgm + DIR/map.yaml. Creates DIR.
  void write_outputs(const std::string& dir) const;

 private:
  const std::vector<Vec3>& rays_for(const PinholeCamera& camera);

  MapBuilderOptions options_;
  OccupancyOctree octree_;
  VoxelCloud cloud_;
  PinholeCamera ray_camera_;
  std::vector<Vec3> rays_;  // unprojected pixel rays (z = 1), cached per camera
};

}  // namespace kestrel::maps
