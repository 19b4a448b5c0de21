#pragma once
// An 8-bit BGRA texture with a mip chain, sized in powers of two so that the rasterizer wraps
// coordinates with a mask instead of a division.
#include <cstdint>
#include <vector>

namespace kestrel::sim {

struct TextureLevel {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> bgra;  // row-major, 4 bytes per texel
};

struct Texture {
  std::vector<TextureLevel> levels;  // levels[0] is full size, each next one half as large
  bool has_alpha = false;            // alpha < 128 is transparent (cut-outs)

  // width and height must be powers of two; builds the mip chain by 2x2 averaging.
  static Texture from_bgra(int width, int height, std::vector<std::uint8_t> bgra, bool has_alpha);
  int width() const { return levels.empty() ? 0 : levels[0].width; }
  int height() const { return levels.empty() ? 0 : levels[0].height; }
};

bool is_power_of_two(int n);

}  // namespace kestrel::sim
