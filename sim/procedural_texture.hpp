#pragma once
// Seeded procedural textures: rich, non-repeating detail (multi-octave value noise, speckles,
// strokes) so that feature trackers find plenty of corners, without any image files.
#include <array>
#include <cstdint>
#include <string>

#include "sim/texture.hpp"

namespace kestrel::sim {

struct TextureSpec {
  // noise | bricks | tiles | posters | wood | car | sky (see procedural_texture.cpp);
  // photo: an image file (the `photo` path), tiled.
  std::string style = "noise";
  std::array<int, 3> color_a{160, 150, 140};  // RGB
  std::array<int, 3> color_b{90, 80, 70};     // RGB
  double scale = 2.0;                         // metres covered by one texture repeat
  double contrast = 1.0;  // 0..1, detail strength (low for feature-poor surfaces)
  int size = 512;         // texels, a power of two
  std::string photo;      // style photo: image path
};

// Deterministic in (spec, seed). Throws kestrel::Error for an unknown style or unreadable photo.
Texture make_texture(const TextureSpec& spec, std::uint64_t seed);

// Mixes integers into a well-spread 64-bit hash (splitmix64 finalizer).
std::uint64_t hash64(std::uint64_t x);
inline std::uint64_t hash_combine(std::uint64_t a, std::uint64_t b) {
  return hash64(a ^ (b + 0x9e3779b97f4a7c15ULL + (a << 6) + (a >> 2)));
}

}  // namespace kestrel::sim
