#pragma once
// A keyframe as place recognition sees it: its static features only.
#include <vector>

#include "loop/loop_detector.hpp"
#include "tracking/frame_features.hpp"

namespace kestrel::loop {

// The place of keyframe `id`: every feature of `features` not labelled dynamic (tracking's
// FeatureStatus::kDynamic), with its undistorted pixel and, where it has depth, its point.
// Walkers cut from the same few photos carry the same words into every keyframe they cross, and
// a mover's points fail the verification's geometry wherever it has walked to. Market, two 60 s
// draws (lock-step, YOLO): loops closed 2 -> 7 and ? -> 5, APE 0.0290 -> 0.0277 and 0.0170 ->
// 0.0157 m (README "Dynamic features").
PlaceView place_view(KeyframeId id, const tracking::FrameFeatures& features,
                     std::vector<KeyframeId> neighbours);

}  // namespace kestrel::loop
