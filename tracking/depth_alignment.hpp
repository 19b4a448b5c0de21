#pragma once
// Frame-to-frame alignment of two depth images (point-to-plane ICP with projective
// association), held by a motion prior. Where the camera sees too little texture to track
// features (a bare wall filling the view), depth still fixes the distance to the wall and two
// of its tilts; the prior (the gyro's rotation, the IMU's translation) keeps the directions
// depth cannot see. Pure: two images in, a relative pose and how well it is constrained out.
#include <vector>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/se3.hpp"

namespace kestrel::tracking {

struct DepthAlignmentOptions {
  // Both images are averaged over cells of cell_px x cell_px pixels: a single reading is too
  // noisy for a surface normal (2.7 cm at 3 m on a D455), a cell's mean point is not.
  int cell_px = 8;
  double min_cell_fill = 0.5;     // share of a cell's pixels with depth
  int normal_cells = 2;           // a reference normal is fitted to (2 n + 1)^2 cells around it
  double depth_sigma_z2 = 0.003;  // one reading's sigma = depth_sigma_floor + this * z^2
  double depth_sigma_floor = 0.001;
  double min_depth_m = 0.2;
  double max_depth_m = 8.0;
  double max_distance_m = 0.08;  // a pair further apart along the normal is no correspondence
  double huber_sigmas = 2.0;
  int iterations = 12;
  int min_points = 300;  // fewer cell correspondences: no alignment
  // Movers' boxes covering more than this share of the depth: none. Walkers filling the view
  // are never all inside their boxes, and what is left of them pulled the pose (market, 18 s:
  // APE 0.06 -> 0.58 m with no such limit).
  double max_excluded_share = 0.25;
  // Data information (1/m^2, 1/rad^2) below which a direction is the prior's alone: 1e6 is
  // a millimetre or a milliradian. On corridor-dark's bare end wall, depth's three weakest
  // directions come at 1e4-1e5 (the normals' noise); where the corridor's corner and floor come
  // into view one of them grows to 5e5 (seed 1, 20.57 s), is left to the prior, and with only
  // the corner tracks on it that frame is the draw's one lost frame. At 3e5 the lost frame just
  // came two frames later, and nine draws lost as many frames with APE a little worse (seed 1
  // 0.062 -> 0.064 m, seed 2 0.118 -> 0.129, the others within 1 mm).
  double min_information = 1e6;
  double max_rms_sigmas = 3.0;  // RMS of the correspondences' residuals, in depth sigmas
  // Corner tracks (below): their pixel sigma, the residual beyond which a track is not the
  // same point (a mover, a corner LK slid off), and the one within which it counts as an inlier.
  double track_pixel_sigma = 1.0;
  double track_max_px = 4.0;
  double track_inlier_px = 2.0;
};

struct DepthAlignmentPrior {
  SE3 T_ref_cur;                    // where the motion model puts the current camera
  double rotation_sigma = 1e-3;     // radians, per axis
  double translation_sigma = 0.01;  // metres, per axis
};

// Pixels of the current image to leave out (a mover's box: its depth moves on its own).
struct PixelBox {
  double x_min = 0, y_min = 0, x_max = 0, y_max = 0;
  bool contains(double x, double y) const {
    return x >= x_min && x <= x_max && y >= y_min && y <= y_max;
  }
};

// A corner of the reference frame, its point from the reference's depth (metres, reference
// camera), found again in the current image at uv_cur (undistorted pixels):
// tracking/corner_tracks.hpp. A reprojection constraint on all six directions of the step.
struct CornerTrack {
  Vec3 p_ref = Vec3::Zero();
  Vec2 uv_cur = Vec2::Zero();
};

struct DepthAlignmentResult {
  bool ok = false;
  SE3 T_ref_cur;   // the prior's pose when !ok
  int points = 0;  // cell correspondences in the last iteration
  double rms_sigmas = 0.0;
  // Directions depth constrained: the smallest eigenvalue of the data's 3x3 translation
  // information, in 1/m^2 (a single plane leaves two directions near zero).
  double weakest_translation_information = 0.0;
  int track_inliers = 0;  // corner tracks within track_inlier_px of the final pose
  // The smallest eigenvalue of what depth and the corner tracks know of the step, without the
  // prior (6x6 information of [rotation rad, translation m]; 1e6: a milliradian or a
  // millimetre in the weakest direction). Under min_information the prior held a direction.
  double weakest_information = 0.0;
};

// depth images are 16-bit (value / scale = metres), of the same size as the camera. Corner
// tracks, when given, weigh in beside the depth (Huber at twice their sigma): along a bare
// wall they fix what depth leaves to the prior.
DepthAlignmentResult align_depth(const Image& ref_depth, double ref_scale, const Image& cur_depth,
                                 double cur_scale, const PinholeCamera& camera,
                                 const DepthAlignmentPrior& prior,
                                 const DepthAlignmentOptions& options = {},
                                 const std::vector<PixelBox>& exclude = {},
                                 const std::vector<CornerTrack>& tracks = {});

}  // namespace kestrel::tracking
