#pragma once
// A 256-bit ORB descriptor as four machine words, so that frames, keyframes and map points can
// hold descriptors without pulling OpenCV into their headers; Hamming distance is four popcounts.
#include <array>
#include <bit>
#include <cstdint>
#include <cstring>

namespace kestrel::tracking {

struct OrbDescriptor {
  std::array<std::uint64_t, 4> words{};

  // From the 32 bytes of one cv::Mat row (CV_8U, 32 columns).
  static OrbDescriptor from_bytes(const std::uint8_t* bytes) {
    OrbDescriptor d;
    std::memcpy(d.words.data(), bytes, sizeof(d.words));
    return d;
  }
  void to_bytes(std::uint8_t* bytes) const { std::memcpy(bytes, words.data(), sizeof(words)); }
  bool operator==(const OrbDescriptor&) const = default;
};

inline int hamming(const OrbDescriptor& a, const OrbDescriptor& b) {
  return std::popcount(a.words[0] ^ b.words[0]) + std::popcount(a.words[1] ^ b.words[1]) +
         std::popcount(a.words[2] ^ b.words[2]) + std::popcount(a.words[3] ^ b.words[3]);
}

}  // namespace kestrel::tracking
