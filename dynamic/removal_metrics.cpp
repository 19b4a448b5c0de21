#include "dynamic/removal_metrics.hpp"

#include <cmath>

namespace kestrel::dynamic {

RemovalCounts count_removal(const std::vector<Vec2>& points,
                            const std::vector<FeatureLabel>& labels, const Image& mask,
                            const std::vector<LabelReason>* reasons) {
  RemovalCounts c;
  if (mask.empty()) return c;
  for (std::size_t i = 0; i < points.size() && i < labels.size(); ++i) {
    const int u = static_cast<int>(std::lround(points[i].x()));
    const int v = static_cast<int>(std::lround(points[i].y()));
    if (u < 0 || v < 0 || u >= mask.width || v >= mask.height) continue;
    const bool truly_dynamic = mask.row<std::uint16_t>(v)[u] != 0;
    const bool removed = labels[i] == FeatureLabel::kDynamic;
    const std::size_t reason =
        reasons && i < reasons->size() ? static_cast<std::size_t>((*reasons)[i]) : 0;
    if (truly_dynamic) {
      ++c.dynamic_total;
      c.dynamic_removed += removed;
      if (!removed && reasons) ++c.dynamic_missed_by_reason[reason];
    } else {
      ++c.static_total;
      c.static_kept += !removed;
      if (removed && reasons) ++c.static_removed_by_reason[reason];
    }
  }
  return c;
}

}  // namespace kestrel::dynamic
