#pragma once
// ORB features spread over the image by grid bucketing, with optional depth back-projection.
// OpenCV stays in the .cpp (pimpl) so that this header is cheap to include.
#include <memory>

#include "core/camera.hpp"
#include "core/frame.hpp"
#include "tracking/frame_features.hpp"

namespace kestrel::tracking {

struct FeatureExtractorOptions {
  int target_features = 1000;  // per frame, after bucketing
  float scale_factor = 1.2f;
  int levels = 8;
  // FAST runs at fast_threshold; when that leaves fewer than fast_fallback_below x the
  // candidates (a dim or bare view), the image is detected again at fast_threshold_fallback
  // (0: never). FAST at 8 was most of ORB's cost: 36k corners on a market frame, 9 of its
  // 10 ms, for 3000 candidates that threshold 20 mostly finds too (ORB keeps the corners of
  // highest FAST score first). Detection median over every 30th frame (one core; 8 -> 20 with
  // the fallback): cafe 10.1 -> 6.0 ms, market 9.5 -> 6.8 ms.
  int fast_threshold = 20;
  int fast_threshold_fallback = 8;
  double fast_fallback_below = 0.8;
  // ORB detects oversample x target candidates; bucketing keeps the best of each cell first so
  // that weak but well-spread corners survive next to strongly textured regions.
  double oversample = 3.0;
  int cell_px = 48;
  // Describe only the keypoints bucketing keeps (ORB detect, then compute on them) instead of
  // all candidates in one pass: the same features, 0.3-1 ms less a frame (interleaved timings
  // on cafe, market and TUM frames on this noisy machine). false: the one pass,
  // kept as the reference the tests compare with.
  bool describe_chosen_only = true;
  double min_depth = 0.1;  // metres; closer readings are sensor noise
  // metres: beyond the D455-class sensors' useful range. Far readings still seed map points (a
  // drone at 8 m sees nothing nearer); local BA weighs them by their disparity.
  double max_depth = 15.0;
  // A keypoint keeps its depth only when its 3x3 neighbourhood agrees within this fraction of
  // the depth (no silhouette, no hole); 0 turns the check off.
  double edge_depth_ratio = 0.05;
  // Dim images: when stretching the 1st..99th percentile of the grey levels to 0..255 takes a
  // gain of at least dim_min_gain, the image is stretched (gain capped at dim_max_gain) before
  // detection and description. dim_max_gain <= 1 turns it off. Measured on corridor-dark (12 s,
  // no movers): 18 lost frames -> 0; office-static 24 s: 1.28 -> 0.98 cm APE.
  double dim_min_gain = 1.8;
  double dim_max_gain = 3.0;
};

class FeatureExtractor {
 public:
  FeatureExtractor(const PinholeCamera& camera, const FeatureExtractorOptions& options = {});
  ~FeatureExtractor();
  FeatureExtractor(FeatureExtractor&&) noexcept;
  FeatureExtractor& operator=(FeatureExtractor&&) noexcept;

  // Features of `image` (8-bit grey or BGR). `ignore` (optional, 8-bit, image size): pixels
  // != 0 get no features. `depth` (optional, 16-bit, registered to image): metres =
  // value / depth_scale. `movers` (optional, 8-bit, image size): pixels != 0 are where movers
  // are expected; features there keep the share the whole image's bucketing gives them and
  // the rest of the image gets target_features of its own (up to twice the target in all).
  // Throws std::invalid_argument on mismatched sizes or pixel types.
  FrameFeatures extract(const Image& image, const Image* ignore = nullptr,
                        const Image* depth = nullptr, double depth_scale = 5000.0, Timestamp t = 0,
                        const Image* movers = nullptr) const;
  FrameFeatures extract(const RgbdFrame& frame, const Image* ignore = nullptr,
                        const Image* movers = nullptr) const {
    return extract(frame.color, ignore, frame.depth.empty() ? nullptr : &frame.depth,
                   frame.depth_scale, frame.t, movers);
  }

  const FeatureExtractorOptions& options() const { return options_; }
  const PinholeCamera& camera() const { return camera_; }

 private:
  struct Impl;
  PinholeCamera camera_;
  FeatureExtractorOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kestrel::tracking
