#pragma once
// What the RGB-D sensor does to the rendered truth: exposure gain, pixel noise, and a
// RealSense-D455-like depth (sigma = a z^2, holes at discontinuities and out of range,
// quantized to 16 bits at 5000 per metre). Noise comes from a seeded table so that the same
// scenario and seed give the same bytes.
#include <cstdint>
#include <vector>

#include "core/image.hpp"
#include "sim/scenario.hpp"

namespace kestrel::sim {

class SensorModel {
 public:
  SensorModel(const SensorSpec& spec, std::uint64_t seed);

  // Exposure gain at time t: the last step at or before t, 1 before the first.
  double exposure_gain(double t) const;
  // bgr: the rendered (possibly blurred) picture; frame: index for the noise stream.
  Image color(const std::vector<std::uint8_t>& bgr, int width, int height, double gain,
              int frame) const;
  // inv_depth: 1/z per pixel, 0 = nothing there. depth_scale: raw units per metre.
  Image depth(const std::vector<float>& inv_depth, int width, int height, double depth_scale,
              int frame) const;
  // A standard normal deviate and a uniform in [0, 1), both pure functions of (key, index).
  double gaussian(std::uint64_t key, std::uint64_t index) const;
  double uniform(std::uint64_t key, std::uint64_t index) const;

 private:
  SensorSpec spec_;
  std::uint64_t seed_;
  std::vector<float> table_;  // standard normal deviates
};

}  // namespace kestrel::sim
