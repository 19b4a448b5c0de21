#pragma once
// DetectionSet as JSON, for `kestrel detect --json` and for result files:
// {"t": seconds, "latency_ms": ..., "boxes": [{"label", "class_id", "score",
//  "x_min", "y_min", "x_max", "y_max"}, ...]}.
#include <string>
#include <vector>

#include "detect/detection.hpp"

namespace kestrel::detect {

struct LabelledDetectionSet {
  std::string source;  // e.g. the image path
  DetectionSet set;
};

// A JSON array with one object per set; each object also has "source". Pretty-printed.
std::string detections_to_json(const std::vector<LabelledDetectionSet>& sets);
// Writes detections_to_json(sets) to `path`; throws kestrel::Error naming the file on failure.
void write_detections_json(const std::string& path, const std::vector<LabelledDetectionSet>& sets);

}  // namespace kestrel::detect
