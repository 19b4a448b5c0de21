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

// What a frame's extraction sets apart from the last frame's movers (`boxes`), before its own
// boxes arrive; the System and the bench's evaluator both take them from here.
struct LastMoverMasks {
  // The movers pixel by pixel (dynamic::mover_silhouette on the last frame's depth): the
  // extractor's `ignore`. Empty when off, with no boxes, or the last depth missing or of
  // another size.
  Image silhouette;
  // mover_mask grown by the budget's margin: the extractor's `movers`. Empty when the margin is
  // negative or there are no boxes.
  Image movers;
  bool any() const { return !silhouette.empty() || !movers.empty(); }
};
LastMoverMasks last_mover_masks(const std::vector<dynamic::BoxRegion>& boxes,
                                const Image& last_depth, double last_depth_scale, int width,
                                int height, int budget_margin_px, bool silhouettes,
                                const dynamic::MoverSilhouetteOptions& opt,
                                const dynamic::DynamicFilterOptions& filter);

}  // namespace kestrel::pipeline
