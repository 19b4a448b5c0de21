#pragma once
// Boxes and labels drawn onto a copy of the frame, for `kestrel detect --out` and debugging.
#include <vector>

#include "core/image.hpp"
#include "detect/detection.hpp"

namespace kestrel::detect {

// Returns an 8-bit BGR copy of `image` (grey is expanded) with each box outlined, dynamic
// classes (default list) in red and the rest in green, and "label score" above it.
Image draw_detections(const Image& image, const std::vector<Detection>& boxes);

}  // namespace kestrel::detect
