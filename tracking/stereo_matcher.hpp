#pragma once
// Depth for left-image ORB features from the right image of a calibrated stereo pair, the way
// ORB-SLAM does it on rectified pairs: ORB features of the right image are moved into the
// rectified geometry (undistorted, rotated by stereoRectify's R1/R2), each left feature takes
// the best descriptor on its row band within the disparity range, and a SAD patch search with
// a parabola fit on the rectified pyramids gives the sub-pixel disparity. The images themselves
// are never resampled for detection, so left features keep their raw-pixel positions and the
// tracker sees an ordinary FrameFeatures with depth, as from an RGB-D camera.
// OpenCV stays in the .cpp (pimpl).
#include <memory>

#include "core/frame.hpp"
#include "core/stereo_rig.hpp"
#include "tracking/feature_extractor.hpp"
#include "tracking/frame_features.hpp"

namespace kestrel::tracking {

struct StereoMatcherOptions {
  // Right-image features (bucketed like the left ones). More than the left's 1000 so that a
  // left feature rarely misses its partner to bucketing; few candidates keep ORB cheap.
  int right_features = 1500;
  double right_oversample = 1.5;
  int max_distance = 75;     // Hamming (ORB-SLAM's (TH_HIGH + TH_LOW) / 2)
  double row_band_px = 2.0;  // rectified row tolerance at level 0, scaled by the level
  int sad_half_window = 5;   // SAD patch 11 x 11 on the feature's pyramid level
  int sad_search = 5;        // +- pixels around the descriptor match, on that level
  double min_depth = 0.1;    // metres
  // Farther than this many baselines the disparity is a few pixels and depth is mostly noise.
  double max_depth_baselines = 60.0;
  double sad_outlier_factor = 2.1;  // drop matches whose SAD exceeds this x the median
};

struct StereoStats {
  int candidates = 0;  // left features considered
  int matched = 0;     // features that got a depth
};

class StereoMatcher {
 public:
  // The rig's cameras may be distorted (radtan or equidistant); features use the same pyramid
  // settings as the left extractor so that levels compare.
  StereoMatcher(const StereoRig& rig, const FeatureExtractorOptions& features,
                const StereoMatcherOptions& options = {});
  ~StereoMatcher();
  StereoMatcher(StereoMatcher&&) noexcept;
  StereoMatcher& operator=(StereoMatcher&&) noexcept;

  // Fills depth and points_c (left camera frame) of `left` features, which were extracted from
  // `left_image` by a FeatureExtractor for rig.left. Features that already have a depth keep it.
  // Throws std::invalid_argument when an image is not 8-bit or its size differs from the rig's.
  StereoStats compute_depth(FrameFeatures& left, const Image& left_image,
                            const Image& right_image) const;

  double baseline() const { return baseline_; }
  // Focal length and principal point of the rectified pair (identical for both cameras).
  double rectified_f() const { return f_; }

 private:
  struct Impl;
  StereoRig rig_;
  FeatureExtractorOptions features_;
  StereoMatcherOptions options_;
  double baseline_ = 0.0;
  double f_ = 0.0;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::tracking
