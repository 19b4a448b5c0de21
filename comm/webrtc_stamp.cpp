#include "comm/webrtc_stamp.hpp"

namespace kestrel::comm {
namespace {

constexpr std::uint64_t kTimeMask = (std::uint64_t{1} << 40) - 1;
constexpr std::uint8_t kWhite = 235;
constexpr std::uint8_t kBlack = 16;

std::uint8_t crc8(std::uint64_t bits56) {
  std::uint8_t crc = 0;
  for (int byte = 6; byte >= 0; --byte) {
    crc ^= static_cast<std::uint8_t>(bits56 >> (8 * byte));
    for (int i = 0; i < 8; ++i) {
      crc = static_cast<std::uint8_t>((crc & 0x80) ? (crc << 1) ^ 0x07 : crc << 1);
    }
  }
  return crc;
}

}  // namespace

std::uint64_t pack_stamp(const FrameStamp& s) {
  const std::uint64_t body = ((s.capture_us & kTimeMask) << 16) | s.frame;
  return (body << 8) | crc8(body);
}

std::optional<FrameStamp> unpack_stamp(std::uint64_t bits) {
  const std::uint64_t body = bits >> 8;
  if (crc8(body) != static_cast<std::uint8_t>(bits & 0xff)) return std::nullopt;
  return FrameStamp{body >> 16, static_cast<std::uint16_t>(body & 0xffff)};
}

void stamp_i420(std::uint8_t* y, int y_stride, std::uint8_t* u, std::uint8_t* v, int uv_stride,
                const FrameStamp& s) {
  const std::uint64_t bits = pack_stamp(s);
  for (int row = 0; row < kStampHeight; ++row) {
    std::uint8_t* line = y + static_cast<std::ptrdiff_t>(row) * y_stride;
    for (int col = 0; col < kStampColumns; ++col) {
      const int bit = 63 - ((row / kStampCell) * kStampColumns + col);
      const std::uint8_t value = ((bits >> bit) & 1) ? kWhite : kBlack;
      for (int x = 0; x < kStampCell; ++x) line[col * kStampCell + x] = value;
    }
  }
  for (int row = 0; row < kStampHeight / 2; ++row) {
    for (int x = 0; x < kStampWidth / 2; ++x) {
      u[static_cast<std::ptrdiff_t>(row) * uv_stride + x] = 128;
      v[static_cast<std::ptrdiff_t>(row) * uv_stride + x] = 128;
    }
  }
}

std::optional<FrameStamp> read_stamp(const std::uint8_t* y, int y_stride) {
  std::uint64_t bits = 0;
  for (int cell = 0; cell < kStampColumns * kStampRows; ++cell) {
    const int cx = (cell % kStampColumns) * kStampCell + kStampCell / 2 - 2;
    const int cy = (cell / kStampColumns) * kStampCell + kStampCell / 2 - 2;
    int sum = 0;
    for (int dy = 0; dy < 4; ++dy) {
      for (int dx = 0; dx < 4; ++dx)
        sum += y[static_cast<std::ptrdiff_t>(cy + dy) * y_stride + cx + dx];
    }
    bits = (bits << 1) | (sum / 16 > (kWhite + kBlack) / 2 ? 1u : 0u);
  }
  return unpack_stamp(bits);
}

}  // namespace kestrel::comm
