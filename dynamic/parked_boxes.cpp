#include "dynamic/parked_boxes.hpp"

#include <algorithm>

#include "core/greedy_pairs.hpp"

namespace kestrel::dynamic {
namespace {

double iou(const BoxRegion& a, const BoxRegion& b) {
  const double w = std::min(a.x_max, b.x_max) - std::max(a.x_min, b.x_min);
  const double h = std::min(a.y_max, b.y_max) - std::max(a.y_min, b.y_min);
  if (w <= 0 || h <= 0) return 0.0;
  const double inter = w * h;
  const double area_a = (a.x_max - a.x_min) * (a.y_max - a.y_min);
  const double area_b = (b.x_max - b.x_min) * (b.y_max - b.y_min);
  return inter / (area_a + area_b - inter);
}

}  // namespace

void ParkedBoxTracker::assign(Timestamp t, std::vector<BoxRegion>& boxes,
                              const std::vector<bool>& parkable) {
  now_ = t;
  std::erase_if(tracks_, [&](const Track& tr) {
    return to_seconds(t - tr.last_seen) > options_.forget_seconds;
  });
  // Greedy by overlap: the best-overlapping pair first, each box and track used once.
  std::vector<ScoredPair> pairs;
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    const bool p = b < parkable.size() && parkable[b];
    for (std::size_t k = 0; k < tracks_.size(); ++k) {
      if (tracks_[k].parkable != p) continue;
      const double o = iou(boxes[b], tracks_[k].box);
      if (o >= options_.min_iou) pairs.push_back({o, b, k});
    }
  }
  track_of_ = greedy_pairs(std::move(pairs), boxes.size(), tracks_.size());
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    if (track_of_[b] < 0) {
      Track tr;
      tr.parkable = b < parkable.size() && parkable[b];
      tracks_.push_back(tr);
      track_of_[b] = static_cast<int>(tracks_.size()) - 1;
    }
    Track& tr = tracks_[static_cast<std::size_t>(track_of_[b])];
    tr.box = boxes[b];
    tr.last_seen = t;
    boxes[b].parked = tr.parkable && tr.parked;
  }
}

void ParkedBoxTracker::observe(const DynamicFilterResult& r) {
  for (std::size_t b = 0; b < track_of_.size(); ++b) {
    Track& tr = tracks_[static_cast<std::size_t>(track_of_[b])];
    if (!tr.parkable) continue;
    const int features = b < r.box_features.size() ? r.box_features[b] : 0;
    const int off = b < r.box_violating.size() ? r.box_violating[b] : 0;
    // Moving as judged from its own features; a frame without geometry calls every box moving
    // and says nothing of this one.
    const bool moving = b < r.box_moving.size() && r.box_moving[b] && features > 0;
    if (moving || (features >= options_.min_features && off > options_.still_share * features)) {
      tr.still = 0;
      tr.parked = false;
      continue;
    }
    if (features < options_.min_features) continue;
    if (tr.still++ == 0) tr.still_since = now_;
    tr.parked = tr.still >= options_.park_judgements &&
                to_seconds(now_ - tr.still_since) >= options_.park_seconds;
  }
  track_of_.clear();  // observe() answers one assign()
}

}  // namespace kestrel::dynamic
