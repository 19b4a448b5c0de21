#include "core/grey_levels.hpp"

#include <algorithm>
#include <array>

namespace kestrel {

GreyRange grey_range(const std::uint8_t* data, int width, int height, std::size_t step,
                     int stride) {
  GreyRange r;
  if (!data || width <= 0 || height <= 0) return r;
  stride = std::max(stride, 1);
  std::array<int, 256> hist{};
  int total = 0;
  for (int y = 0; y < height; y += stride) {
    const std::uint8_t* row = data + static_cast<std::size_t>(y) * step;
    for (int x = 0; x < width; x += stride, ++total) ++hist[row[x]];
  }
  const int tail = std::max(1, total / 100);
  int lo = 0;
  for (int acc = 0; lo < 255 && (acc += hist[static_cast<std::size_t>(lo)]) < tail;) ++lo;
  int hi = 255;
  for (int acc = 0; hi > 0 && (acc += hist[static_cast<std::size_t>(hi)]) < tail;) --hi;
  r.lo = lo;
  r.hi = std::max(hi, lo);
  return r;
}

}  // namespace kestrel
