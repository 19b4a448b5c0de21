#include "dynamic/removal_metrics.hpp"

#include <algorithm>
#include <cmath>

namespace kestrel::dynamic {
namespace {

// Whether a pixel with another id than `id` lies within r (Chebyshev) of (u, v).
bool other_within(const Image& mask, int u, int v, int r, std::uint16_t id) {
  for (int y = std::max(v - r, 0); y <= std::min(v + r, mask.height - 1); ++y) {
    const std::uint16_t* row = mask.row<std::uint16_t>(y);
    for (int x = std::max(u - r, 0); x <= std::min(u + r, mask.width - 1); ++x) {
      if (row[x] != id) return true;
    }
  }
  return false;
}

}  // namespace

RemovalCounts count_removal(const std::vector<Vec2>& points,
                            const std::vector<FeatureLabel>& labels, const Image& mask,
                            const std::vector<LabelReason>* reasons) {
  RemovalCounts c;
  if (mask.empty()) return c;
  for (std::size_t i = 0; i < points.size() && i < labels.size(); ++i) {
    const int u = static_cast<int>(std::lround(points[i].x()));
    const int v = static_cast<int>(std::lround(points[i].y()));
    if (u < 0 || v < 0 || u >= mask.width || v >= mask.height) continue;
    const std::uint16_t id = mask.row<std::uint16_t>(v)[u];
    const bool truly_dynamic = id != 0;
    const bool on_outline = other_within(mask, u, v, RemovalCounts::kOutlinePx, id);
    const bool removed = labels[i] == FeatureLabel::kDynamic;
    const std::size_t reason =
        reasons && i < reasons->size() ? static_cast<std::size_t>((*reasons)[i]) : 0;
    if (truly_dynamic) {
      ++c.dynamic_total;
      c.dynamic_removed += removed;
      if (!removed && reasons) ++c.dynamic_missed_by_reason[reason];
      if (on_outline) {
        ++c.dynamic_near_outline;
        c.dynamic_near_outline_removed += removed;
      }
    } else {
      ++c.static_total;
      c.static_kept += !removed;
      if (on_outline) {
        ++c.static_near_outline;
        c.static_near_outline_kept += !removed;
      }
      if (removed && reasons) ++c.static_removed_by_reason[reason];
    }
  }
  return c;
}

}  // namespace kestrel::dynamic
