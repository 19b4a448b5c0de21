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
};

struct DynamicFilterResult {
  std::vector<FeatureLabel> labels;
  std::vector<LabelReason> reasons;
  std::vector<float> epipolar_px;  // -1 when unknown
  std::vector<float> residual_px;  // to the ego-motion homography / rotation; -1 unknown
  std::vector<int> box_of;         // index of the box holding the feature, -1 none
  std::vector<bool> box_moving;    // per input box
  bool geometry_valid = false;
  bool degenerate_motion = false;     // little translation: homography test where depth is missing
  bool motion_3d = false;             // ego-motion from depth + PnP was used
  double outside_threshold_px = 0.0;  // the adaptive threshold used this frame
  int tracked = 0;                    // features with valid flow

  std::size_t count(FeatureLabel l) const;
};

DynamicFilterResult classify_features(const DynamicFilterInput& in,
                                      const DynamicFilterOptions& opt);

}  // namespace kestrel::dynamic
