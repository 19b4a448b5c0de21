#pragma once
// What a detector reports for one frame. Core types only (no OpenCV), so tracking, dynamic
// filtering and the semantic map can consume detections without pulling in a DNN runtime.
#include <algorithm>
#include <string>
#include <vector>

#include "core/timestamp.hpp"

namespace kestrel::detect {

// An axis-aligned box in image pixels of the frame that was passed to the detector,
// x_min/y_min inclusive, x_max/y_max exclusive (the io::SequenceBox convention).
struct Detection {
  int class_id = -1;  // index into the canonical COCO list (coco_class_id), -1 if not a COCO class
  std::string label;  // canonical COCO name: "person", "motorcycle", "dining table"
  float score = 0.0f;
  float x_min = 0, y_min = 0, x_max = 0, y_max = 0;

  float width() const { return std::max(0.0f, x_max - x_min); }
  float height() const { return std::max(0.0f, y_max - y_min); }
  float area() const { return width() * height(); }
};

struct DetectionSet {
  Timestamp t = 0;  // stamp of the frame the boxes belong to
  std::vector<Detection> boxes;
  double latency_ms = 0.0;  // time the detector took (or, for the oracle, the simulated delay)
};

// Intersection over union; 0 when either box is empty.
inline float iou(const Detection& a, const Detection& b) {
  const float w = std::min(a.x_max, b.x_max) - std::max(a.x_min, b.x_min);
  const float h = std::min(a.y_max, b.y_max) - std::max(a.y_min, b.y_min);
  if (w <= 0 || h <= 0) return 0.0f;
  const float inter = w * h;
  const float uni = a.area() + b.area() - inter;
  return uni > 0 ? inter / uni : 0.0f;
}

}  // namespace kestrel::detect
