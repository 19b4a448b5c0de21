#pragma once
// A keyframe as place recognition sees it: its static features only.
#include <vector>

#include "loop/loop_detector.hpp"
#include "tracking/frame_features.hpp"

namespace kestrel::loop {

// The place of keyframe `id`: every feature of `features` not labelled dynamic (tracking's
// FeatureStatus::kDynamic), with its undistorted pixel and, where it has depth, its point.
// Walkers cut from the same few photos carry the same words into every keyframe they cross, and
// a mover's points fail the verification's geometry wherever it has walked to. Sixteen lock-step
// 60 s draws (README "Dynamic features"): market's loops closed 0-2 -> 5-7 a draw, APE summed
// 0.399 -> 0.383 m.
PlaceView place_view(KeyframeId id, const tracking::FrameFeatures& features,
                     std::vector<KeyframeId> neighbours);

}  // namespace kestrel::loop
