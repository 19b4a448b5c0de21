#pragma once
// Which features are static: the seed system's hybrid rule, made stricter.
//  * Every feature is followed back to the previous frame with pyramidal Lucas-Kanade flow
//    (forward-backward checked).
//  * The camera's own motion is fitted on features outside the detector's dynamic boxes:
//    a RANSAC fundamental matrix, and a RANSAC homography (or the IMU-predicted rotation,
//    K R K^-1, when given).
//  * Inside a dynamic box a feature is kept only if its distance to its epipolar line is at
//    most `epipolar_threshold_px` (3 px, the seed's rule) AND its box is not judged moving as a
//    whole; boxes are judged one by one from their own features' flow, so two overlapping
//    movers do not contaminate each other.
//  * Outside boxes, geometry alone catches movers the detector missed (unknown classes, false
//    negatives): a feature whose epipolar distance, or — when the camera barely translates and
//    epipolar geometry is degenerate — whose residual against the ego-motion homography exceeds
//    a threshold adapted to this frame's static residual spread, is dynamic.
// Pure and single-threaded: a test calls it on two frames.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/eigen_types.hpp"
#include "core/image.hpp"

namespace kestrel::dynamic {

enum class FeatureLabel : std::uint8_t { kStatic, kDynamic, kUnknown };

enum class LabelReason : std::uint8_t {
  kStaticGeometry,   // outside boxes, consistent with ego-motion
  kStaticInBox,      // inside a box but on its epipolar line and its box is not moving
  kEpipolarInBox,    // inside a box, epipolar distance above the threshold
  kMovingBox,        // inside a box whose features move as a group
  kEpipolarOutside,  // outside boxes, epipolar distance above the adaptive threshold
  kFlowResidual,     // outside boxes, residual to the ego-motion homography/IMU too large
  kNoFlowInBox,      // flow lost inside a box: treated as dynamic
  kNoFlow,           // flow lost outside boxes: unknown
  kNoGeometry,       // too few features to fit ego-motion: boxes alone decided
  kForegroundInBox,  // inside a box, at the depth of the detected object itself
  kDepthChange,      // its depth changed unlike a static point's under the ego-motion
  kLongBaseline,     // consistent against the previous frame, moved against an older one
};

const char* to_string(LabelReason r);

struct BoxRegion {
  float x_min = 0, y_min = 0, x_max = 0, y_max = 0;
  bool contains(float x, float y) const {
    return x >= x_min && x < x_max && y >= y_min && y < y_max;
  }
};

enum class FilterMode { kHybrid, kDetectionOnly, kGeometryOnly, kOff };
const char* to_string(FilterMode m);
std::optional<FilterMode> filter_mode_from_string(const std::string& name);

struct DynamicFilterOptions {
  FilterMode mode = FilterMode::kHybrid;
  double epipolar_threshold_px = 3.0;     // inside boxes (the seed's rule)
  double outside_min_threshold_px = 3.0;  // floor of the adaptive thresholds outside boxes
  double residual3d_min_px = 2.5;         // floor of the threshold on the depth-based residual
  double adaptive_k = 4.0;  // threshold = median + k * 1.4826 * MAD of static residuals
  double ransac_threshold_px = 1.0;
  double moving_box_fraction = 0.4;   // a box is moving when this share of its features is
  double foreground_band_m = 0.35;    // object thickness around the box core's depth
  double foreground_band_rel = 0.12;  // ... or this fraction of the depth, if larger
  int lk_window = 15;
  int lk_levels = 3;
  double fb_max_error_px = 1.0;  // forward-backward consistency of LK
  double still_flow_px = 1.0;    // median rotation-compensated flow below: camera still
  // Depth consistency (with the previous depth image): |measured - predicted depth| / depth^2
  // above median + k * sigma of the background's, and above this floor (1/m; a structured-
  // light sensor's noise is about 0.003 z^2), and above depth_min_change_m.
  double depth_k = 4.0;
  double depth_floor_per_m = 0.01;
  double depth_min_change_m = 0.05;
};

struct DynamicFilterInput {
  const Image* prev_gray = nullptr;  // 8-bit, 1 channel
  const Image* cur_gray = nullptr;
  std::vector<Vec2> points;  // feature positions in the current frame (pixels)
  // Depth of each feature in metres (0 = none), aligned with points; may be empty. With depth,
  // a box is split into the detected object (at the depth of the box's core) and what is seen
  // around it: the object's features are dynamic whether it moves this instant or not (a
  // person who stands still now walks off later); the background keeps the epipolar test.
  std::vector<double> depth_m;
  std::vector<BoxRegion> boxes;  // dynamic-class detections matched to this frame
  Mat3 K = Mat3::Identity();
  std::optional<Mat3> R_cur_prev;  // IMU-predicted camera rotation, prev camera into current
  // The previous frame's depth image (16-bit, metres = value / depth_scale), optional. With
  // it, a point whose depth changed otherwise than the ego-motion predicts is dynamic: a
  // walker coming straight at the camera, or walking just ahead of it, barely moves in the
  // image but its depth does not follow the camera's motion.
  const Image* prev_depth = nullptr;
  double depth_scale = 5000.0;
};

struct DynamicFilterResult {
  std::vector<FeatureLabel> labels;
  std::vector<LabelReason> reasons;
  std::vector<float> epipolar_px;    // -1 when unknown
  std::vector<float> residual_px;    // to the ego-motion homography / rotation; -1 unknown
  std::vector<float> residual3d_px;  // to the depth + PnP ego-motion prediction; -1 unknown
  std::vector<float> depth_change;   // |measured - predicted previous depth| / depth^2; -1 unknown
  std::vector<int> box_of;           // index of the box holding the feature, -1 none
  std::vector<bool> box_moving;      // per input box
  bool geometry_valid = false;
  bool degenerate_motion = false;     // little translation: homography test where depth is missing
  bool motion_3d = false;             // ego-motion from depth + PnP was used
  double outside_threshold_px = 0.0;  // the adaptive threshold used this frame
  double depth_threshold = 0.0;       // the adaptive depth-change threshold (1/m); 0 unused
  int tracked = 0;                    // features with valid flow

  std::size_t count(FeatureLabel l) const;
};

DynamicFilterResult classify_features(const DynamicFilterInput& in,
                                      const DynamicFilterOptions& opt);

// Multi-frame evidence. A slow mover, or one walking just ahead of the camera, shifts less than
// the noise between two consecutive frames, but its displacement adds up over several: judged
// against a frame further back (classify_features with that frame as `prev_gray`, same points)
// the geometry sees it. `short_baseline` is the result against the previous frame, `long_baseline`
// against an older one (both for the same current points). A feature the short baseline left
// static becomes dynamic when the long baseline finds it off the ego-motion by its 3D residual
// (> long_residual_px) and the short baseline already leans that way (> short_residual_px); both
// residuals must exist (depth and flow at both baselines), so lost flow over the long baseline
// or a missing depth never removes a feature.
struct MultiFrameOptions {
  double long_residual_px = 4.0;
  double short_residual_px = 1.0;
};
DynamicFilterResult combine_baselines(const DynamicFilterResult& short_baseline,
                                      const DynamicFilterResult& long_baseline,
                                      const MultiFrameOptions& opt = {});

}  // namespace kestrel::dynamic
