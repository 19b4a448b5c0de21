#pragma once
// Where the last frame's movers were, for the feature extractor to set apart before this
// frame's own boxes arrive (tracking::FeatureExtractor::extract's `movers`).
#include <vector>

#include "core/image.hpp"
#include "dynamic/dynamic_filter.hpp"
#include "dynamic/mover_silhouette.hpp"

namespace kestrel::pipeline {

// The margin of the movers' feature budget when it is on (SystemOptions::mover_budget_margin_px,
// off by default since the silhouettes). Before them, twelve lock-step 60 s draws (cafe 1-3,
// market 1-4, ugv-loop, uav-zigzag 1-4; APE summed): one budget 0.356 m, margin 8 px 0.379,
// 24 px 0.315; sixteen: 0.542 -> 0.398 at 24 px (README "Dynamic features").
inline constexpr int kMoverBudgetMarginPx = 24;

// 255 inside the boxes that are not parked (a parked vehicle is scenery), grown by `margin`
// pixels; 0 elsewhere.
Image mover_mask(int width, int height, const std::vector<dynamic::BoxRegion>& boxes, int margin);

// The last frame's movers pixel by pixel (dynamic::mover_silhouette on its depth), for a frame of
// width x height: the extractor's `ignore`. Empty when there are no boxes, or the last depth is
// missing or of another size.
Image last_movers_silhouette(const Image& last_depth, double last_depth_scale,
                             const std::vector<dynamic::BoxRegion>& boxes, int width, int height,
                             const dynamic::MoverSilhouetteOptions& opt,
                             const dynamic::DynamicFilterOptions& filter);

}  // namespace kestrel::pipeline
