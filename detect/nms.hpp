#pragma once
// Per-class non-maximum suppression: a person box never suppresses the bicycle under it.
#include <vector>

#include "detect/detection.hpp"

namespace kestrel::detect {

// Keeps, per class_id (label when class_id < 0), the highest-scoring box of every group whose
// IoU exceeds `iou_threshold`. Boxes with score <= 0 are dropped. The result is sorted by
// descending score.
std::vector<Detection> non_max_suppression(const std::vector<Detection>& boxes,
                                           float iou_threshold);

}  // namespace kestrel::detect
