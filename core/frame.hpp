#pragma once
#include <string>
#include <variant>

#include "core/image.hpp"
#include "core/imu.hpp"
#include "core/timestamp.hpp"

namespace kestrel {

// Colour (or grey) image with depth registered to it. Depth is 16-bit, metres = value / scale.
struct RgbdFrame {
  Timestamp t = 0;
  Image color;  // 8-bit, 1 or 3 channels (BGR order, as OpenCV decodes)
  Image depth;  // 16-bit, 1 channel; empty for a monocular stream
  double depth_scale = 5000.0;
  std::string source;  // the file it came from, for error messages and reports
};

// Rectified or raw stereo pair at one stamp (hardware-synchronized).
struct StereoFrame {
  Timestamp t = 0;
  Image left;
  Image right;
  std::string source;
};

// What a dataset reader or the simulator yields: one time-ordered stream.
using Measurement = std::variant<ImuSample, RgbdFrame, StereoFrame>;

inline Timestamp stamp_of(const Measurement& m) {
  return std::visit([](const auto& x) { return x.t; }, m);
}

}  // namespace kestrel
