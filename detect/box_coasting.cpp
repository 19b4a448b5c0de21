#include "detect/box_coasting.hpp"

#include <algorithm>

#include "core/greedy_pairs.hpp"

namespace kestrel::detect {

Detection BoxCoaster::predicted(const Track& tr, Timestamp t) const {
  const auto dt = static_cast<float>(to_seconds(t - tr.last_seen));
  Detection d = tr.box;
  d.x_min += tr.vx * dt;
  d.x_max += tr.vx * dt;
  d.y_min += tr.vy * dt;
  d.y_max += tr.vy * dt;
  return d;
}

std::vector<Detection> BoxCoaster::update(Timestamp t, const std::vector<Detection>& detections,
                                          int width, int height) {
  std::erase_if(tracks_, [&](const Track& tr) {
    return t < tr.last_seen || to_seconds(t - tr.last_seen) > options_.forget_seconds;
  });
  // Greedy by overlap with where each track should be now: the best pair first.
  std::vector<Detection> expected;
  expected.reserve(tracks_.size());
  for (const Track& tr : tracks_) expected.push_back(predicted(tr, t));
  std::vector<ScoredPair> pairs;
  for (std::size_t d = 0; d < detections.size(); ++d) {
    for (std::size_t k = 0; k < tracks_.size(); ++k) {
      if (tracks_[k].box.label != detections[d].label) continue;
      const float o = iou(detections[d], expected[k]);
      if (o >= options_.min_iou) pairs.push_back({o, d, k});
    }
  }
  const std::vector<int> track_of =
      greedy_pairs(std::move(pairs), detections.size(), tracks_.size());
  std::vector<bool> seen(tracks_.size(), false);
  for (std::size_t d = 0; d < detections.size(); ++d) {
    if (track_of[d] < 0) continue;
    const auto k = static_cast<std::size_t>(track_of[d]);
    seen[k] = true;
    Track& tr = tracks_[k];
    const Detection& now = detections[d];
    const auto dt = static_cast<float>(to_seconds(t - tr.last_seen));
    if (dt > 0) {
      tr.vx = 0.5f * ((now.x_min + now.x_max) - (tr.box.x_min + tr.box.x_max)) / dt;
      tr.vy = 0.5f * ((now.y_min + now.y_max) - (tr.box.y_min + tr.box.y_max)) / dt;
    }
    tr.box = now;
    tr.last_seen = t;
    ++tr.detections;
    tr.carried = 0;
  }
  std::vector<Detection> out;
  const std::size_t known = tracks_.size();
  for (std::size_t k = 0; k < known; ++k) {
    Track& tr = tracks_[k];
    if (seen[k] || tr.detections < options_.min_detections || tr.carried >= options_.max_frames) {
      continue;
    }
    Detection d = expected[k];
    d.x_min = std::clamp(d.x_min, 0.0f, static_cast<float>(width));
    d.x_max = std::clamp(d.x_max, 0.0f, static_cast<float>(width));
    d.y_min = std::clamp(d.y_min, 0.0f, static_cast<float>(height));
    d.y_max = std::clamp(d.y_max, 0.0f, static_cast<float>(height));
    ++tr.carried;
    if (d.width() > 0 && d.height() > 0) out.push_back(std::move(d));
  }
  for (std::size_t d = 0; d < detections.size(); ++d) {
    if (track_of[d] >= 0) continue;
    Track tr;
    tr.box = detections[d];
    tr.last_seen = t;
    tr.detections = 1;
    tracks_.push_back(std::move(tr));
  }
  return out;
}

}  // namespace kestrel::detect
