#pragma once
// The capture time of a video frame, stamped into its pixels so that it survives any encoder
// and needs no RTP header extension (webrtcbin 1.22 cannot attach one per buffer, and a browser
// hands header extensions to no script). 64 bits in a 16x4 grid of 8x8 luma cells at the
// top-left corner, most significant bit first, white (235) = 1, black (16) = 0, chroma neutral:
// 8x8 cells on the 8x8 transform grid survive H.264 at any sane bitrate, and the page reads
// them back with one drawImage of a 128x32 region (web/station.js, decodeStamp).
//
//   bits 63..24  capture wall-clock time in microseconds modulo 2^40 (12.7 days: the reader
//                takes the value nearest to its own offset-corrected clock)
//   bits 23..8   frame number modulo 2^16
//   bits  7..0   CRC-8 (polynomial 0x07) of the 7 bytes above, so a misread is rejected
#include <cstdint>
#include <optional>

namespace kestrel::comm {

constexpr int kStampCell = 8;
constexpr int kStampColumns = 16;
constexpr int kStampRows = 4;
constexpr int kStampWidth = kStampCell * kStampColumns;  // 128 px
constexpr int kStampHeight = kStampCell * kStampRows;    // 32 px

struct FrameStamp {
  std::uint64_t capture_us = 0;  // modulo 2^40 once read back
  std::uint16_t frame = 0;
};

std::uint64_t pack_stamp(const FrameStamp& s);
std::optional<FrameStamp> unpack_stamp(std::uint64_t bits);  // nullopt on a CRC mismatch

// Writes the stamp into an I420 image of at least kStampWidth x kStampHeight.
void stamp_i420(std::uint8_t* y, int y_stride, std::uint8_t* u, std::uint8_t* v, int uv_stride,
                const FrameStamp& s);
// Reads it back from a luma plane (each cell's 4x4 centre, threshold halfway).
std::optional<FrameStamp> read_stamp(const std::uint8_t* y, int y_stride);

}  // namespace kestrel::comm
