#pragma once
// The 2D grid's free-space rule, as pure functions over plain data.
//
// A cell of the height band is free only when the band's lowest `clearance` metres above it are
// seen free (room for a robot's body, not just a gap under a parked car's body). Two things
// spare a cell that rule without loosening it where it matters:
//  - a clearance layer that no keyframe's camera ever had in its view, because it lay below or
//    above the field of view or nearer than the sensor's minimum depth (a blind zone), cannot
//    have been seen by anyone: it is judged by the layers that were seen. A ground robot's camera
//    0.4 m up never sees the floor band within ~0.7 m of itself; the space under a car's body it
//    does see (the body is in view), and occluded space stays unknown.
//  - footprint clearing (as ROS costmaps do): the disc a ground robot's body stood on is free.
#include <cstdint>
#include <vector>

#include "core/camera.hpp"
#include "core/eigen_types.hpp"
#include "core/se3.hpp"
#include "maps/occupancy_grid.hpp"

namespace kestrel::maps {

// The band as the OctoMap saw it, column by column.
struct BandColumns {
  // kOccupied: an occupied voxel lies in the band; kFree: only free voxels of the band (at least
  // one); kUnknown: nothing of the band seen.
  OccupancyGrid grid;
  int layers = 0;             // clearance layers, counted up from layer_base (at most 31)
  double layer_base = 0.0;    // world z of the lowest layer's bottom, metres
  double layer_height = 0.1;  // metres (the voxel size)
  // Per cell of grid: bit l set when clearance layer l was seen free. Empty when layers == 0.
  std::vector<std::uint32_t> free_layers;

  std::uint32_t all_layers() const { return layers > 0 ? (std::uint32_t{1} << layers) - 1 : 0; }
  double layer_center_z(int l) const { return layer_base + (l + 0.5) * layer_height; }
};

// Where one keyframe's rays could carve free space: its pinhole frustum (distortion ignored)
// from near_depth (along the optical axis) to far_range (along the ray).
struct ViewFrustum {
  Mat3 R_c_w = Mat3::Identity();
  Vec3 t_c_w = Vec3::Zero();
  Vec2 eye_xy = Vec2::Zero();  // the camera centre's world x, y
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;
  int width = 640, height = 480;
  double near_depth = 0.3;
  double far_range = 8.0;
};

ViewFrustum frustum_of(const SE3& T_w_c, const PinholeCamera& camera, double near_depth,
                       double far_range);
enum class Visibility {
  kInView,     // p_w is in the frustum
  kBlindZone,  // not, but it lies within the image's columns: below or above the field of
               // view, or nearer than near_depth (the floor right in front of a low camera)
  kOutside,    // beside or behind the view, or out of its range
};
Visibility visibility(const ViewFrustum& v, const Vec3& p_w);
bool in_frustum(const ViewFrustum& v, const Vec3& p_w);

// Per cell of c.grid: the clearance layers that are not seen free, that no view had in its
// frustum and that some view had in its blind zone (at the cell's centre, the layer's
// mid-height). A layer only beside every view (the edge of a view cone, where a slanted
// frustum sees the top of a column and not its foot) is not excused. Only cells that are
// band-free (kFree) are examined; the others get 0.
std::vector<std::uint32_t> unobservable_layers(const BandColumns& c,
                                               const std::vector<ViewFrustum>& views);

// The grid: occupied cells stay occupied; a band-free cell is free when each clearance layer is
// seen free or excused (excused: null, or a per-cell mask as unobservable_layers gives), else
// unknown. layers == 0: every band-free cell is free.
OccupancyGrid resolve_columns(const BandColumns& c, const std::vector<std::uint32_t>* excused);

// A ground robot's body at one moment: world x, y of its centre and its radius (metres).
struct Footprint {
  Vec2 xy = Vec2::Zero();
  double radius = 0.0;
};

// Footprint clearing: unknown cells whose centre lies within a footprint's radius become free
// (the robot stood there); occupied cells keep their evidence, unless over_obstacles: where the
// robot stands now, nothing else can be (ROS costmap_2d clears its footprint so too), and an
// obstacle there is a passer-by the map caught or the pose's error against a wall. The grid
// grows (new cells unknown) to hold every footprint's disc; an empty grid becomes one that holds
// them at `resolution`.
OccupancyGrid clear_footprints(const OccupancyGrid& g, const std::vector<Footprint>& footprints,
                               double resolution = 0.1, bool over_obstacles = false);

}  // namespace kestrel::maps
