#pragma once
// Corners of one frame found again in the next, for the frames whose ORB features the map
// cannot hold. At corridor-dark's bare end wall ORB finds 1000 corners of which about two repeat
// from frame to frame, yet the wall's faint blotches hold: Shi-Tomasi corners on the lightly
// blurred image, followed into the next frame by Lucas-Kanade forward and backward, land within
// 1-2 px of where the true motion puts them (35-64 of 84-91 tracks with depth per frame pair).
// With the previous frame's depth each is a reprojection constraint on all six directions of
// the step, where the depth of one plane fixes three: align_depth takes both
// (tracking/depth_alignment.hpp). Pure: two frames in, tracks out.
#include <vector>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "tracking/depth_alignment.hpp"

namespace kestrel::tracking {

struct CornerTrackOptions {
  int max_corners = 300;
  double corner_quality = 0.01;  // of the strongest corner's Shi-Tomasi score
  double corner_min_distance_px = 4.0;
  int corner_block_px = 7;  // a faint blotch needs a wider structure tensor than ORB's FAST ring
  double blur_sigma = 1.0;  // sensor noise out of the corners and the flow
  int flow_window_px = 15;
  int flow_levels = 2;                   // pyramid levels above full resolution
  double max_forward_backward_px = 0.3;  // a track that does not come back is no track
  double min_depth_m = 0.2;
  double max_depth_m = 8.0;
};

struct CornerTracks {
  int corners = 0;                  // corners with depth in the reference frame
  std::vector<CornerTrack> tracks;  // of them, followed forward and back
};

// ref_gray and cur_gray are 8-bit single-channel images of one size; ref_depth is 16-bit
// (value / ref_scale = metres) on ref_gray's pixels. Corners inside `exclude` (movers' boxes)
// in either frame are left out. Throws std::invalid_argument on images of the wrong kind.
CornerTracks follow_corners(const Image& ref_gray, const Image& ref_depth, double ref_scale,
                            const Image& cur_gray, const PinholeCamera& camera,
                            const CornerTrackOptions& options = {},
                            const std::vector<PixelBox>& exclude = {});

}  // namespace kestrel::tracking
