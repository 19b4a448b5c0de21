#pragma once
// Dynamic-feature removal measured against ground truth (the definition): a feature is
// truly dynamic when its pixel lies in the simulator's mover mask. "Removed" means labelled
// dynamic; "kept" means not labelled dynamic (unknown features stay usable).
#include <array>
#include <cstddef>
#include <vector>

#include "core/eigen_types.hpp"
#include "core/image.hpp"
#include "dynamic/dynamic_filter.hpp"

namespace kestrel::dynamic {

struct RemovalCounts {
  std::size_t dynamic_total = 0;
  std::size_t dynamic_removed = 0;
  std::size_t static_total = 0;
  std::size_t static_kept = 0;
  // Features on a mover's outline: a static one with a mover pixel within kOutlinePx
  // (Chebyshev) of its own, a dynamic one with a pixel of another id (static or another mover)
  // that near. Their 15 px flow window and 31 px descriptor patch straddle the outline, so what
  // they see moves partly with one side and partly with the other. Reported beside the issue's
  // figures, which count them by their own pixel like any other.
  static constexpr int kOutlinePx = 7;  // half the flow window
  std::size_t static_near_outline = 0;
  std::size_t static_near_outline_kept = 0;
  std::size_t dynamic_near_outline = 0;
  std::size_t dynamic_near_outline_removed = 0;
  // Where the errors come from, by the filter's reason (index: LabelReason).
  static constexpr std::size_t kReasons =
      static_cast<std::size_t>(LabelReason::kRimOnObject) + 1;  // the last reason
  std::array<std::size_t, kReasons> dynamic_missed_by_reason{};
  std::array<std::size_t, kReasons> static_removed_by_reason{};

  double removed_percent() const {
    return dynamic_total ? 100.0 * dynamic_removed / dynamic_total : 100.0;
  }
  double kept_percent() const { return static_total ? 100.0 * static_kept / static_total : 100.0; }
  // The two figures counting only features away from every mover's outline.
  double removed_away_from_outlines_percent() const {
    const std::size_t n = dynamic_total - dynamic_near_outline;
    return n ? 100.0 * (dynamic_removed - dynamic_near_outline_removed) / n : 100.0;
  }
  double kept_away_from_outlines_percent() const {
    const std::size_t n = static_total - static_near_outline;
    return n ? 100.0 * (static_kept - static_near_outline_kept) / n : 100.0;
  }
  RemovalCounts& operator+=(const RemovalCounts& o) {
    dynamic_total += o.dynamic_total;
    dynamic_removed += o.dynamic_removed;
    static_total += o.static_total;
    static_kept += o.static_kept;
    static_near_outline += o.static_near_outline;
    static_near_outline_kept += o.static_near_outline_kept;
    dynamic_near_outline += o.dynamic_near_outline;
    dynamic_near_outline_removed += o.dynamic_near_outline_removed;
    for (std::size_t i = 0; i < kReasons; ++i) {
      dynamic_missed_by_reason[i] += o.dynamic_missed_by_reason[i];
      static_removed_by_reason[i] += o.static_removed_by_reason[i];
    }
    return *this;
  }
};

// mask: 16-bit mover ids (0 = static) of the same frame; points in pixels. reasons (optional,
// aligned with labels) fill the per-reason error counts.
RemovalCounts count_removal(const std::vector<Vec2>& points,
                            const std::vector<FeatureLabel>& labels, const Image& mask,
                            const std::vector<LabelReason>* reasons = nullptr);

}  // namespace kestrel::dynamic
