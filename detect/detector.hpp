#pragma once
// The seam between the pipeline's detection thread and any detector: a real network
// (YoloFastest) or ground truth with noise (OracleDetector). Implementations are plain
// single-threaded objects; the pipeline owns the thread.
#include <string>

#include "core/image.hpp"
#include "detect/detection.hpp"

namespace kestrel::detect {

class Detector {
 public:
  virtual ~Detector() = default;
  // `image` is 8-bit BGR (3 channels) or grey (1 channel); `t` is its stamp, copied into the
  // result so that the DetectionBuffer can match boxes to frames.
  virtual DetectionSet detect(const Image& image, Timestamp t) = 0;
  virtual std::string name() const = 0;
};

}  // namespace kestrel::detect
