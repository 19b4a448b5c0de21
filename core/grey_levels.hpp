#pragma once
// Contrast of an 8-bit grey image from a sparse grid of its pixels: what the feature extractor
// judges a dim image by before stretching it.
#include <cstddef>
#include <cstdint>

namespace kestrel {

struct GreyRange {
  int lo = 0;    // the 1st percentile's grey level
  int hi = 255;  // the 99th
  int spread() const { return hi - lo; }
};

// `data`: the first row of a width x height image whose rows are `step` bytes apart; every
// `stride`-th pixel of every `stride`-th row is counted.
GreyRange grey_range(const std::uint8_t* data, int width, int height, std::size_t step,
                     int stride = 2);

}  // namespace kestrel
