#include "mapping/map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace kestrel::mapping {

int MapPoint::predict_level(double distance, double scale_factor, int levels) const {
  if (!(distance > 0.0) || !(max_distance > 0.0)) return 0;
  const int level =
      static_cast<int>(std::ceil(std::log(max_distance / distance) / std::log(scale_factor)));
  return std::clamp(level, 0, levels - 1);
}

int Map::tracked_points(KeyframeId kid, int min_observations) const {
  const Keyframe* kf = keyframe(kid);
  if (!kf) return 0;
  int n = 0;
  for (PointId pid : kf->point_of_feature) {
    const MapPoint* p = point(pid);
    if (p && static_cast<int>(p->observations.size()) >= min_observations) ++n;
  }
  return n;
}

Map::Map(const Map& other)
    : keyframes_(other.keyframes_),
      points_(other.points_),
      recent_points_(other.recent_points_),
      next_keyframe_(other.next_keyframe_),
      next_point_(other.next_point_) {
  reindex_keyframes();
}

Map& Map::operator=(const Map& other) {
  if (this != &other) {
    keyframes_ = other.keyframes_;
    points_ = other.points_;
    recent_points_ = other.recent_points_;
    next_keyframe_ = other.next_keyframe_;
    next_point_ = other.next_point_;
    reindex_keyframes();
  }
  return *this;
}

void Map::index_keyframe(KeyframeId id, Keyframe* kf) {
  if (id < 0) return;
  const auto at = static_cast<std::size_t>(id);
  if (at >= keyframe_at_.size()) {
    if (!kf || at > 16 * (keyframes_.size() + 64)) return;
    keyframe_at_.resize(at + 1, nullptr);
  }
  keyframe_at_[at] = kf;
}

void Map::reindex_keyframes() {
  keyframe_at_.clear();
  for (auto& [id, kf] : keyframes_) index_keyframe(id, &kf);
}

void Map::restore(std::map<KeyframeId, Keyframe> keyframes,
                  std::unordered_map<PointId, MapPoint> points) {
  keyframes_ = std::move(keyframes);
  reindex_keyframes();
  points_ = std::move(points);
  recent_points_.clear();
  next_keyframe_ = keyframes_.empty() ? 0 : keyframes_.rbegin()->first + 1;
  next_point_ = 0;
  for (const auto& [id, p] : points_) next_point_ = std::max(next_point_, id + 1);
}

KeyframeId Map::add_keyframe(Timestamp t, const SE3& T_w_c, FrameFeatures features) {
  const KeyframeId id = next_keyframe_++;
  Keyframe& kf = keyframes_[id];
  index_keyframe(id, &kf);
  kf.id = id;
  kf.t = t;
  kf.T_w_c = T_w_c;
  kf.point_of_feature.assign(features.size(), kNoPoint);
  kf.features = std::move(features);
  return id;
}

PointId Map::add_point(const Vec3& p_w, KeyframeId kf, int feature) {
  const PointId id = next_point_++;
  MapPoint& p = points_[id];
  p.id = id;
  p.p_w = p_w;
  p.first_keyframe = kf;
  recent_points_.push_back(id);
  add_observation(id, kf, feature);
  update_point(id);
  return id;
}

void Map::add_observation(PointId pid, KeyframeId kid, int feature) {
  MapPoint* p = point(pid);
  Keyframe* kf = keyframe(kid);
  if (!p || !kf || feature < 0 || feature >= static_cast<int>(kf->point_of_feature.size())) return;
  // A feature sees one point and a point is seen once per keyframe: replace stale links.
  const PointId old = kf->point_of_feature[static_cast<std::size_t>(feature)];
  if (old != kNoPoint && old != pid) {
    if (MapPoint* o = point(old)) {
      o->observations.erase(kid);
      update_point(old);  // its descriptor and normal follow its observations at once
    }
  }
  if (auto it = p->observations.find(kid); it != p->observations.end() && it->second != feature) {
    kf->point_of_feature[static_cast<std::size_t>(it->second)] = kNoPoint;
  }
  p->observations[kid] = feature;
  kf->point_of_feature[static_cast<std::size_t>(feature)] = pid;
}

void Map::erase_observation(PointId pid, KeyframeId kid) {
  MapPoint* p = point(pid);
  if (!p) return;
  auto it = p->observations.find(kid);
  if (it == p->observations.end()) return;
  if (Keyframe* kf = keyframe(kid))
    kf->point_of_feature[static_cast<std::size_t>(it->second)] = kNoPoint;
  p->observations.erase(it);
  if (p->observations.empty()) {
    erase_point(pid);
  } else {
    update_point(pid);
  }
}

void Map::erase_point(PointId pid) {
  auto it = points_.find(pid);
  if (it == points_.end()) return;
  for (const auto& [kid, feature] : it->second.observations) {
    if (Keyframe* kf = keyframe(kid)) {
      auto& slot = kf->point_of_feature[static_cast<std::size_t>(feature)];
      if (slot == pid) slot = kNoPoint;
    }
  }
  points_.erase(it);
}

void Map::update_point(PointId pid) {
  update_point_descriptor(pid);
  update_point_geometry(pid);
}

void Map::update_point_descriptor(PointId pid) {
  MapPoint* p = point(pid);
  if (!p || p->observations.empty()) return;
  // The newest kDescriptorViews views only: the choice costs the square of the views, and where
  // a place is revisited for minutes a point gathers hundreds of them (market, 300 s: keyframe
  // insertion and culling, which update every point they touch, reached 15-64 ms at p90 on the
  // tracking thread). The newest views are also the appearance tracking meets next.
  std::vector<const OrbDescriptor*> descs;
  descs.reserve(std::min(p->observations.size(), kDescriptorViews));
  for (auto it = p->observations.rbegin();
       it != p->observations.rend() && descs.size() < kDescriptorViews; ++it) {
    if (const Keyframe* kf = keyframe(it->first))
      descs.push_back(&kf->features.descriptors[static_cast<std::size_t>(it->second)]);
  }
  // Oldest first, as before the cap: among views whose medians tie, the oldest stays chosen.
  std::reverse(descs.begin(), descs.end());
  if (descs.empty()) return;
  // The representative descriptor has the least median distance to the others.
  if (descs.size() <= 2) {
    p->descriptor = *descs.front();
    return;
  }
  // Each distance once (the matrix is symmetric): half the Hamming work of a keyframe's
  // insertion, which updates every point it tracked.
  const std::size_t n = descs.size();
  std::vector<int> dist(n * n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      dist[i * n + j] = dist[j * n + i] = tracking::hamming(*descs[i], *descs[j]);
    }
  }
  int best_median = std::numeric_limits<int>::max();
  std::vector<int> d(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::copy_n(dist.begin() + static_cast<std::ptrdiff_t>(i * n), n, d.begin());
    std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
    if (d[d.size() / 2] < best_median) {
      best_median = d[d.size() / 2];
      p->descriptor = *descs[i];
    }
  }
}

void Map::update_point_geometry(PointId pid) {
  MapPoint* p = point(pid);
  if (!p || p->observations.empty()) return;
  Vec3 normal = Vec3::Zero();
  const Keyframe* ref = nullptr;
  int ref_feature = 0;
  for (const auto& [kid, feature] : p->observations) {
    const Keyframe* kf = keyframe(kid);
    if (!kf) continue;
    const Vec3 ray = p->p_w - kf->T_w_c.translation();
    if (ray.norm() > 0.0) normal += ray.normalized();
    if (!ref) {
      ref = kf;
      ref_feature = feature;
    }
  }
  if (!ref) return;
  if (normal.norm() > 0.0) p->normal = normal.normalized();
  const FrameFeatures& f = ref->features;
  const double dist = (p->p_w - ref->T_w_c.translation()).norm();
  const int level = f.keypoints[static_cast<std::size_t>(ref_feature)].level;
  p->max_distance = dist * f.level_scale(level);
  p->min_distance = p->max_distance / f.level_scale(f.levels - 1);
}

int Map::create_points_from_depth(KeyframeId kid, int max_new, double max_depth) {
  Keyframe* kf = keyframe(kid);
  if (!kf) return 0;
  const FrameFeatures& f = kf->features;
  std::vector<std::pair<double, int>> candidates;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (kf->point_of_feature[i] != kNoPoint || !f.has_depth(i) || f.depth[i] > max_depth) continue;
    if (f.status[i] == tracking::FeatureStatus::kDynamic) continue;
    candidates.emplace_back(f.depth[i], static_cast<int>(i));
  }
  std::sort(candidates.begin(), candidates.end());
  int created = 0;
  for (const auto& [z, i] : candidates) {
    if (created >= max_new) break;
    add_point(kf->T_w_c * f.points_c[static_cast<std::size_t>(i)], kid, i);
    ++created;
  }
  return created;
}

int Map::cull_points(KeyframeId current, const CullingOptions& options) {
  int removed = 0;
  std::vector<PointId> keep;
  keep.reserve(recent_points_.size());
  for (PointId pid : recent_points_) {
    MapPoint* p = point(pid);
    if (!p) continue;
    const KeyframeId age = current - p->first_keyframe;
    if (p->found_ratio() < options.min_found_ratio ||
        (age >= 2 && static_cast<int>(p->observations.size()) < options.min_observations)) {
      erase_point(pid);
      ++removed;
    } else if (age < 3) {
      keep.push_back(pid);  // still on probation
    }
  }
  recent_points_ = std::move(keep);
  return removed;
}

void Map::update_connections(KeyframeId kid, int min_shared) {
  Keyframe* kf = keyframe(kid);
  if (!kf) return;
  // Shared points per other keyframe, tallied by id (ids are dense) and read back in id order:
  // a std::map of counts cost a tree walk per observation, and sorting every observation
  // grew with the square of a revisited place's history. A loaded map's ids may be sparse (any
  // non-negative values): then a hash map tallies them.
  const auto span = static_cast<std::size_t>(std::max<KeyframeId>(next_keyframe_, 0));
  const bool dense = span <= 16 * (keyframes_.size() + 64);
  std::vector<int> tally(dense ? span : 0, 0);
  std::unordered_map<KeyframeId, int> sparse_tally;
  std::vector<KeyframeId> touched;
  auto count_of = [&](KeyframeId other) -> int& {
    if (!dense) return sparse_tally[other];
    const auto at = static_cast<std::size_t>(other);
    if (at >= tally.size()) tally.resize(at + 1, 0);
    return tally[at];
  };
  for (PointId pid : kf->point_of_feature) {
    const MapPoint* p = point(pid);
    if (!p) continue;
    for (const auto& [other, feature] : p->observations) {
      (void)feature;
      if (other == kid || other < 0) continue;
      if (count_of(other)++ == 0) touched.push_back(other);
    }
  }
  std::sort(touched.begin(), touched.end());
  std::vector<std::pair<KeyframeId, int>> counts;
  counts.reserve(touched.size());
  for (KeyframeId other : touched) counts.emplace_back(other, count_of(other));
  for (auto& [other, w] : kf->connections) {
    if (Keyframe* o = keyframe(other)) o->connections.erase(kid);
    (void)w;
  }
  kf->connections.clear();
  KeyframeId best = -1;
  int best_count = 0;
  for (const auto& [other, count] : counts) {
    if (count > best_count) {
      best_count = count;
      best = other;
    }
    if (count >= min_shared) kf->connections[other] = count;
  }
  // Keep at least the strongest link so that no keyframe becomes an island.
  if (kf->connections.empty() && best >= 0) kf->connections[best] = best_count;
  for (const auto& [other, count] : kf->connections) {
    if (Keyframe* o = keyframe(other)) o->connections[kid] = count;
  }
}

bool Map::seen_by_others(const MapPoint& p, KeyframeId kid, int level, int observers) const {
  int seen = 0;
  for (const auto& [other, feature] : p.observations) {
    if (other == kid) continue;
    const Keyframe* o = keyframe(other);
    if (!o || feature < 0 || feature >= static_cast<int>(o->features.keypoints.size())) continue;
    if (o->features.keypoints[static_cast<std::size_t>(feature)].level <= level + 1 &&
        ++seen >= observers) {
      return true;
    }
  }
  return false;
}

const MapPoint* Map::close_point(const Keyframe& kf, std::size_t i, double max_depth) const {
  const auto& ff = kf.features;
  if (i >= ff.depth.size() || ff.depth[i] <= 0.0 || ff.depth[i] > max_depth) return nullptr;
  return point(kf.point_of_feature[i]);
}

double Map::redundancy(KeyframeId kid, double max_depth, int observers) const {
  const Keyframe* kf = keyframe(kid);
  if (!kf) return 0.0;
  int close = 0, redundant = 0;
  for (std::size_t i = 0; i < kf->point_of_feature.size(); ++i) {
    const MapPoint* p = close_point(*kf, i, max_depth);
    if (!p) continue;
    ++close;
    redundant += seen_by_others(*p, kid, kf->features.keypoints[i].level, observers) ? 1 : 0;
  }
  return close > 0 ? static_cast<double>(redundant) / close : 0.0;
}

bool Map::is_redundant(KeyframeId kid, double max_depth, int observers, double fraction) const {
  const Keyframe* kf = keyframe(kid);
  if (!kf) return false;
  // Counting the close points first costs no walk through their views; then the walks stop as
  // soon as the answer is known. On a place revisited for minutes a point has 25 views or more,
  // and most neighbours judged are not redundant: a tenth of their points decides.
  int close = 0;
  for (std::size_t i = 0; i < kf->point_of_feature.size(); ++i) {
    close += close_point(*kf, i, max_depth) ? 1 : 0;
  }
  if (close == 0) return false;
  const double needed = fraction * close;  // redundant > needed
  int redundant = 0, judged = 0;
  for (std::size_t i = 0; i < kf->point_of_feature.size(); ++i) {
    const MapPoint* p = close_point(*kf, i, max_depth);
    if (!p) continue;
    ++judged;
    if (seen_by_others(*p, kid, kf->features.keypoints[i].level, observers)) {
      if (++redundant > needed) return true;
    }
    if (redundant + (close - judged) <= needed) return false;
  }
  return false;
}

void Map::erase_keyframe(KeyframeId kid) {
  auto it = keyframes_.find(kid);
  if (it == keyframes_.end()) return;
  std::vector<KeyframeId> neighbours;
  for (const auto& [other, w] : it->second.connections) {
    (void)w;
    if (Keyframe* o = keyframe(other)) o->connections.erase(kid);
    neighbours.push_back(other);
  }
  const std::vector<PointId> seen = it->second.point_of_feature;
  const std::optional<GyroLink> through = it->second.gyro;
  index_keyframe(kid, nullptr);
  keyframes_.erase(it);
  for (auto& [id, kf] : keyframes_) {
    (void)id;
    if (!kf.gyro || kf.gyro->from != kid) continue;
    if (!through) {
      kf.gyro.reset();
      continue;
    }
    kf.gyro->R_c_from = kf.gyro->R_c_from * through->R_c_from;
    kf.gyro->from = through->from;
    kf.gyro->dt_s += through->dt_s;
    kf.gyro->sigma_rad = std::hypot(kf.gyro->sigma_rad, through->sigma_rad);
    kf.gyro->imu.reset();
  }
  for (PointId pid : seen) {
    MapPoint* p = point(pid);
    if (!p) continue;
    p->observations.erase(kid);
    if (p->observations.empty()) {
      points_.erase(pid);
    } else {
      update_point(pid);  // first_keyframe stays: it dates the point's birth for culling
    }
  }
  // Weights between two other keyframes do not change (a point the erased one saw keeps
  // everyone else's observations); only a neighbour left without any link needs its strongest
  // one found again. Recomputing every neighbour cost hundreds of milliseconds per culled
  // keyframe once a place had been revisited for minutes (market, 300 s: culling at 64 ms per
  // keyframe at p90, 179 at p99, on the tracking thread).
  for (KeyframeId other : neighbours) {
    const Keyframe* o = keyframe(other);
    if (o && o->connections.empty()) update_connections(other);
  }
}

std::vector<KeyframeId> Map::covisible(KeyframeId kid, int n) const {
  const Keyframe* kf = keyframe(kid);
  if (!kf) return {};
  std::vector<std::pair<int, KeyframeId>> v;
  for (const auto& [other, w] : kf->connections) v.emplace_back(w, other);
  std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second > b.second;
  });
  std::vector<KeyframeId> out;
  for (std::size_t i = 0; i < v.size() && static_cast<int>(i) < n; ++i) out.push_back(v[i].second);
  return out;
}

const Keyframe* Map::find_keyframe(KeyframeId id) const {
  if (id >= 0 && static_cast<std::size_t>(id) < keyframe_at_.size()) {
    if (const Keyframe* kf = keyframe_at_[static_cast<std::size_t>(id)]) return kf;
  }
  auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}
Keyframe* Map::keyframe(KeyframeId id) {
  // The non-const Map owns the keyframe: dropping the const find_keyframe added is safe.
  return const_cast<Keyframe*>(find_keyframe(id));
}
const Keyframe* Map::keyframe(KeyframeId id) const { return find_keyframe(id); }
MapPoint* Map::point(PointId id) {
  if (id == kNoPoint) return nullptr;
  auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}
const MapPoint* Map::point(PointId id) const {
  if (id == kNoPoint) return nullptr;
  auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}

}  // namespace kestrel::mapping
