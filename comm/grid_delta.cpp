#include "comm/grid_delta.hpp"

#include <zlib.h>

namespace kestrel::comm {
namespace {

void put_varint(std::vector<std::uint8_t>& out, std::uint64_t x) {
  while (x >= 0x80) {
    out.push_back(static_cast<std::uint8_t>(x | 0x80));
    x >>= 7;
  }
  out.push_back(static_cast<std::uint8_t>(x));
}

bool get_varint(const std::vector<std::uint8_t>& in, std::size_t& pos, std::uint64_t& x) {
  x = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (pos >= in.size()) return false;
    const std::uint8_t b = in[pos++];
    x |= static_cast<std::uint64_t>(b & 0x7f) << shift;
    if (!(b & 0x80)) return true;
  }
  return false;
}

std::vector<std::uint8_t> deflate_bytes(const std::vector<std::uint8_t>& raw) {
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<std::uint8_t> out(size);
  if (compress2(out.data(), &size, raw.data(), static_cast<uLong>(raw.size()), 6) != Z_OK) {
    return {};
  }
  out.resize(size);
  return out;
}

// Inflates at most `limit` bytes: a hostile stream cannot make us allocate more than a grid.
bool inflate_bytes(const std::vector<std::uint8_t>& z, std::size_t limit,
                   std::vector<std::uint8_t>& out) {
  z_stream s{};
  if (inflateInit(&s) != Z_OK) return false;
  out.assign(limit + 1, 0);
  s.next_in = const_cast<Bytef*>(z.data());
  s.avail_in = static_cast<uInt>(z.size());
  s.next_out = out.data();
  s.avail_out = static_cast<uInt>(out.size());
  const int rc = inflate(&s, Z_FINISH);
  const std::size_t produced = out.size() - s.avail_out;
  inflateEnd(&s);
  if (rc != Z_STREAM_END || produced > limit) return false;
  out.resize(produced);
  return true;
}

}  // namespace

GridDeltaMsg make_grid_delta(const GridState& base, const GridState& current, Timestamp t) {
  GridDeltaMsg msg;
  msg.t = t;
  msg.width = current.width;
  msg.height = current.height;
  msg.resolution = current.resolution;
  msg.origin = current.origin;
  const bool keyframe = base.cells.size() != current.cells.size() || base.width != current.width ||
                        base.origin != current.origin || base.resolution != current.resolution;
  msg.base_seq = keyframe ? 0 : base.seq;
  msg.seq = current.seq != 0 ? current.seq : base.seq + 1;
  std::vector<std::uint8_t> raw;
  const std::size_t n = current.cells.size();
  std::size_t i = 0, last_end = 0;
  while (i < n) {
    if (!keyframe && base.cells[i] == current.cells[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < n && (keyframe || base.cells[j] != current.cells[j])) ++j;
    put_varint(raw, i - last_end);
    put_varint(raw, j - i);
    raw.insert(raw.end(), current.cells.begin() + static_cast<std::ptrdiff_t>(i),
               current.cells.begin() + static_cast<std::ptrdiff_t>(j));
    last_end = j;
    i = j;
  }
  msg.runs_zlib = deflate_bytes(raw);
  return msg;
}

bool apply_grid_delta(GridState& grid, const GridDeltaMsg& delta) {
  const std::size_t n = static_cast<std::size_t>(delta.width) * delta.height;
  std::vector<std::uint8_t> cells;
  if (delta.base_seq == 0) {
    cells.assign(n, 255);
  } else {
    if (delta.base_seq != grid.seq || grid.cells.size() != n || grid.width != delta.width) {
      return false;
    }
    cells = grid.cells;
  }
  // Each run costs at least two header bytes plus one value: runs never exceed 3n bytes.
  std::vector<std::uint8_t> raw;
  if (!inflate_bytes(delta.runs_zlib, 3 * n + 16, raw)) return false;
  std::size_t pos = 0, cell = 0;
  while (pos < raw.size()) {
    std::uint64_t skip = 0, count = 0;
    if (!get_varint(raw, pos, skip) || !get_varint(raw, pos, count)) return false;
    if (skip > n - cell || count > n - cell - skip || count > raw.size() - pos) return false;
    cell += skip;
    std::copy(raw.begin() + static_cast<std::ptrdiff_t>(pos),
              raw.begin() + static_cast<std::ptrdiff_t>(pos + count),
              cells.begin() + static_cast<std::ptrdiff_t>(cell));
    pos += count;
    cell += count;
  }
  grid.cells = std::move(cells);
  grid.seq = delta.seq;
  grid.width = delta.width;
  grid.height = delta.height;
  grid.resolution = delta.resolution;
  grid.origin = delta.origin;
  return true;
}

}  // namespace kestrel::comm
