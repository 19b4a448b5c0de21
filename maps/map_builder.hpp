#pragma once
// Builds the clean maps from keyframes (DESIGN.md maps/): a voxel-downsampled coloured and
// labelled cloud, an OctoMap with free-space carving and the 2D grid of a height band, from
// static pixels only. One call per keyframe from the mapping thread; no threads here.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/se3.hpp"
#include "maps/free_space_rule.hpp"
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
  // Depth noise is per pixel (sigma = depth_noise_z2 x depth^2, 15 cm at 7 m for a D455-like
  // sensor): every sampled reading is averaged with its (2r+1)^2 neighbours that lie on the
  // same surface (within 2.5 sigma + 2 cm), which divides the noise by up to 2r+1. Unsmoothed,
  // a far wall's hits scatter over several voxels behind it that no ray ever carves.
  int smooth_radius = 2;          // 0: raw readings
  double depth_noise_z2 = 0.003;  // the sensor's depth sigma / depth^2
  // A ray stops carving free space where it comes within this many voxels of its surface
  // (measured across the surface, whose normal comes from the depth around the pixel): at a
  // grazing angle that is long before the end point, so a table top or a seat seen from afar
  // is not cleared by the rays that land on it. Capped at grazing_max_margin metres.
  double grazing_clearance = 1.0;   // voxels
  double grazing_max_margin = 1.0;  // metres
  OctreeOptions octree;
  double grid_z_min = 0.10;  // height band (world z, metres) projected into the 2D grid:
  double grid_z_max = 1.60;  // above the floor, up to what a ground robot can hit
  // Free cells of the grid that no path through free cells (4-connected) joins to where a
  // camera has been are unknown, not free: space seen only under or inside something (rays
  // under a parked car's body carve the band's lower voxels, and the band above them is never
  // seen from a low camera) is no place a robot can go, and its floor says nothing of what is
  // above. A camera's nearest free cell within this radius (metres) seeds the fill; 0: off.
  double reachable_seed_radius = 3.0;
  // A cell is free only when its band is seen free over this height from the band's base:
  // room for a robot's body, not only a gap under something (a car's body 0.3 m up).
  double grid_free_clearance = 0.4;  // metres (0.1..0.5 m up); 0: any free voxel of the band
  // ... except the clearance layers of a cell that no keyframe's camera had in view (a low
  // camera's blind zone around itself, maps/free_space_rule.hpp): those are judged by what was
  // seen of the band. false: every clearance layer must be seen free.
  bool clearance_spares_unobservable = true;
};

// The options for a depth sensor of range depth_max (metres; unset: the defaults' 8 m):
// surfaces are trusted to a metre short of it and rays carve free space to it. A drone 8 m up
// looking 45 degrees down sees the ground 11 m away: with the defaults' 7 and 8 m no surface of it
// was trusted and no ray carved there, so its grid held little more than its take-off and landing
// (uav-zigzag, truth poses, kestrel sim's sensor to 13 m: grid IoU 0.16 -> 0.94, residue 0.9%; the
// bench in the plaza was free, A* planned into it). Trusting surfaces to 10 m there: IoU 0.95,
// residue 1.25%; 11 m: 0.94, 1.16%. Using the sensor's own noise (0.002) for the smoothing's
// same-surface test instead of 0.003: IoU 0.90-0.93, residue 1.3-1.5% (it averages fewer
// neighbours).
MapBuilderOptions map_builder_options(std::optional<double> depth_max);

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
  // A ground robot's body where the frame was taken: its disc is free in the grid (footprint
  // clearing). None for a hand-held camera or a flying one (it passes over obstacles).
  std::optional<Footprint> footprint;
};

struct MapBoxRegion {  // a pixel box (max exclusive), e.g. a moving detection
  int x_min = 0, y_min = 0, x_max = 0, y_max = 0;
};

// width*height mask, 1 everywhere except inside the boxes (grown by `margin` pixels).
// The depth (depth units) at (u, v) averaged with its neighbours within `radius` pixels that
// hold a reading within 2.5 sigma + 2 cm of it (sigma = noise_z2 x depth^2), then again with
// those within that of the first mean; 0 where (u, v) has no reading. Neighbours on another
// surface (across a depth edge) are left out.
double smoothed_depth(const Image& depth, int u, int v, int radius, double noise_z2,
                      double depth_scale);

// Free cells of g that no 4-connected path of free cells joins to a seed become unknown. Each
// seed point starts the fill at its nearest free cell within seed_radius metres (none: it
// seeds nothing).
void mark_unreachable_unknown(OccupancyGrid& g, const std::vector<Vec2>& seeds_xy,
                              double seed_radius);

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
  // The 2D grid of the height band under the free-space rule (grid_free_clearance and
  // clearance_spares_unobservable), the keyframes' footprints cleared; free cells no camera
  // could reach are unknown (options.reachable_seed_radius).
  OccupancyGrid grid() const;

  // DIR/cloud.ply, DIR/octomap.bt, DIR/map.pgm + DIR/map.yaml. Creates DIR.
  void write_outputs(const std::string& dir) const;

 private:
  const std::vector<Vec3>& rays_for(const PinholeCamera& camera);
  // Where the free-space carving of the ray to pixel (u, v) (depth z, world point p_w, camera
  // centre o_w) stops: grazing_clearance voxels across the surface short of it.
  Eigen::Vector3f carve_end(const MapKeyframe& kf, int u, int v, float z,
                            const Eigen::Vector3f& p_w, const Eigen::Vector3f& o_w) const;

  MapBuilderOptions options_;
  OccupancyOctree octree_;
  VoxelCloud cloud_;
  PinholeCamera ray_camera_;
  std::vector<Vec3> rays_;             // unprojected pixel rays (z = 1), cached per camera
  std::vector<Vec2> camera_xy_;        // where the keyframes were taken (world x, y)
  std::vector<ViewFrustum> views_;     // what each keyframe's camera could see
  std::vector<Footprint> footprints_;  // where a ground robot stood
};

}  // namespace kestrel::maps
