#include "dynamic/object_depth.hpp"

#include <algorithm>
#include <array>
#include <cstdint>

namespace kestrel::dynamic {

namespace {

// Sorts 16-bit depth readings in two counting passes (low byte, then high byte): a walker's box
// core holds thousands of them each frame, and std::sort took 0.1 ms of the filter's 3 there.
void sort_readings(std::vector<std::uint16_t>& v) {
  std::vector<std::uint16_t> tmp(v.size());
  for (const int shift : {0, 8}) {
    std::array<std::size_t, 257> start{};
    for (const std::uint16_t x : v) ++start[((x >> shift) & 0xff) + 1];
    for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
    for (const std::uint16_t x : v) tmp[start[(x >> shift) & 0xff]++] = x;
    v.swap(tmp);
  }
}

}  // namespace

BoxRegion box_core(const BoxRegion& box) {
  const float w = box.x_max - box.x_min, h = box.y_max - box.y_min;
  return {box.x_min + 0.25f * w, box.y_min + 0.15f * h, box.x_max - 0.25f * w,
          box.y_max - 0.35f * h};
}

double foreground_band(double depth_m, const DynamicFilterOptions& opt) {
  return std::max(opt.foreground_band_m, opt.foreground_band_rel * depth_m);
}

std::vector<double> largest_surface(const Image& depth, double scale, const BoxRegion& region,
                                    const DynamicFilterOptions& opt) {
  std::vector<std::uint16_t> raw;  // sorted as read: the order of their depths
  const int x0 = std::max(0, static_cast<int>(region.x_min));
  const int x1 = std::min(depth.width, static_cast<int>(region.x_max));
  const int y0 = std::max(0, static_cast<int>(region.y_min));
  const int y1 = std::min(depth.height, static_cast<int>(region.y_max));
  for (int v = y0; v < y1; v += 2) {
    const std::uint16_t* row = depth.row<std::uint16_t>(v);
    for (int u = x0; u < x1; u += 2) {
      if (row[u]) raw.push_back(row[u]);
    }
  }
  sort_readings(raw);
  const auto z = [&](std::size_t k) { return raw[k] / scale; };
  std::size_t best_lo = 0, best_hi = 0, hi = 0;
  for (std::size_t lo = 0; lo < raw.size(); ++lo) {
    const double width = 2.0 * foreground_band(z(lo), opt);
    hi = std::max(hi, lo);
    while (hi < raw.size() && z(hi) <= z(lo) + width) ++hi;
    if (hi - lo > best_hi - best_lo) best_lo = lo, best_hi = hi;
  }
  std::vector<double> out;
  out.reserve(best_hi - best_lo);
  for (std::size_t k = best_lo; k < best_hi; ++k) out.push_back(z(k));
  return out;
}

}  // namespace kestrel::dynamic
