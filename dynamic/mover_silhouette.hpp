#pragma once
// Where a frame's movers are, pixel by pixel, from their boxes and the depth image: the next
// frame's features are extracted elsewhere (tracking::FeatureExtractor::extract's `ignore`).
//
// A walker's corners compete with the scenery's for the extractor's buckets and suppress the
// scenery's corners beside them, so which static corners a crowded frame keeps changes frame to
// frame as the walkers move, and the scenery's tracks break. Labelling every feature from the
// simulator's truth masks (a temporary experiment) left market 1 / 2 at 0.022 / 0.018 m APE
// against 0.0067 / 0.0060 for the same draws without movers; extracting no features on the
// truth masks' movers, at 0.0072 / 0.0077, and on the previous frame's truth masks grown by 6
// px, at 0.0083 / 0.0074: the labels were never the gap, the extraction was.
#include <vector>

#include "core/image.hpp"
#include "dynamic/dynamic_filter.hpp"

namespace kestrel::dynamic {

struct MoverSilhouetteOptions {
  // Grown by this many pixels: the movers and the camera move between the frame the silhouette
  // is taken from and the one it is used on (figures in the README, "Dynamic features").
  int grow_px = 12;
  // A box whose core holds fewer readings of its largest surface (a car beyond the sensor's
  // range) has no silhouette: its features are the filter's to judge.
  int min_readings = 8;
};

// 8-bit, the depth image's size: 255 where the boxes' objects are, 0 elsewhere. An object is
// the depth readings inside its box (one that is not parked) within the dynamic filter's
// foreground band (DynamicFilterOptions::foreground_band_m / _rel) of the depth of the largest
// surface in the box's core (object_depth.hpp), grown by grow_px. depth: 16-bit, metres = value /
// depth_scale. Throws std::invalid_argument on another pixel type, a scale that is not positive
// or options out of range.
Image mover_silhouette(const Image& depth, double depth_scale, const std::vector<BoxRegion>& boxes,
                       const MoverSilhouetteOptions& opt, const DynamicFilterOptions& filter);

// Throws std::invalid_argument, naming the field, unless grow_px >= 0, min_readings >= 1,
// filter.foreground_band_m > 0 and filter.foreground_band_rel >= 0.
void validate(const MoverSilhouetteOptions& opt, const DynamicFilterOptions& filter);

}  // namespace kestrel::dynamic
