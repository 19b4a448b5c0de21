#include "sim/texture.hpp"

#include <stdexcept>
#include <string>

namespace kestrel::sim {

bool is_power_of_two(int n) { return n > 0 && (n & (n - 1)) == 0; }

Texture Texture::from_bgra(int width, int height, std::vector<std::uint8_t> bgra, bool has_alpha) {
  if (!is_power_of_two(width) || !is_power_of_two(height) ||
      bgra.size() != static_cast<std::size_t>(width) * height * 4) {
    throw std::invalid_argument("Texture: size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is not a power of two or data mismatch");
  }
  Texture tex;
  tex.has_alpha = has_alpha;
  tex.levels.push_back({width, height, std::move(bgra)});
  while (tex.levels.back().width > 1 && tex.levels.back().height > 1) {
    const TextureLevel& src = tex.levels.back();
    TextureLevel dst;
    dst.width = src.width / 2;
    dst.height = src.height / 2;
    dst.bgra.resize(static_cast<std::size_t>(dst.width) * dst.height * 4);
    for (int y = 0; y < dst.height; ++y) {
      for (int x = 0; x < dst.width; ++x) {
        for (int c = 0; c < 4; ++c) {
          const auto at = [&](int xx, int yy) {
            return static_cast<int>(
                src.bgra[(static_cast<std::size_t>(yy) * src.width + xx) * 4 + c]);
          };
          const int sum = at(2 * x, 2 * y) + at(2 * x + 1, 2 * y) + at(2 * x, 2 * y + 1) +
                          at(2 * x + 1, 2 * y + 1);
          dst.bgra[(static_cast<std::size_t>(y) * dst.width + x) * 4 + c] =
              static_cast<std::uint8_t>((sum + 2) / 4);
        }
      }
    }
    tex.levels.push_back(std::move(dst));
  }
  return tex;
}

}  // namespace kestrel::sim
