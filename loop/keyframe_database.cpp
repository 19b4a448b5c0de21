#include "loop/keyframe_database.hpp"

#include <algorithm>

namespace kestrel::loop {

void KeyframeDatabase::add(KeyframeId id, BowVector bow) {
  erase(id);
  for (const auto& [w, weight] : bow.entries) inverted_[w].push_back(id);
  bows_.emplace(id, std::move(bow));
}

void KeyframeDatabase::erase(KeyframeId id) {
  const auto it = bows_.find(id);
  if (it == bows_.end()) return;
  for (const auto& [w, weight] : it->second.entries) {
    auto& list = inverted_[w];
    list.erase(std::remove(list.begin(), list.end(), id), list.end());
    if (list.empty()) inverted_.erase(w);
  }
  bows_.erase(it);
}

void KeyframeDatabase::clear() {
  bows_.clear();
  inverted_.clear();
}

const BowVector* KeyframeDatabase::bow(KeyframeId id) const {
  const auto it = bows_.find(id);
  return it == bows_.end() ? nullptr : &it->second;
}

std::vector<LoopCandidate> KeyframeDatabase::query(const BowVector& bow,
                                                   const std::vector<KeyframeId>& neighbours,
                                                   const std::set<KeyframeId>& exclude,
                                                   const KeyframeDatabaseOptions& options) const {
  double normaliser = 0.0;
  bool first = true;
  for (KeyframeId n : neighbours) {
    const BowVector* b = this->bow(n);
    if (!b) continue;
    const double s = l1_score(bow, *b);
    normaliser = first ? s
                       : (options.least_similar_neighbour ? std::min(normaliser, s)
                                                          : std::max(normaliser, s));
    first = false;
  }

  // The inverted index limits scoring to keyframes sharing at least one word.
  std::unordered_map<KeyframeId, int> shared;
  for (const auto& [w, weight] : bow.entries) {
    const auto it = inverted_.find(w);
    if (it == inverted_.end()) continue;
    for (KeyframeId id : it->second)
      if (!exclude.count(id)) ++shared[id];
  }
  std::vector<LoopCandidate> out;
  for (const auto& [id, count] : shared) {
    LoopCandidate c;
    c.id = id;
    c.score = l1_score(bow, bows_.at(id));
    c.normalized = normaliser > 0.0 ? c.score / normaliser : c.score;
    if (c.score >= options.min_score && c.normalized >= options.min_normalized) out.push_back(c);
  }
  std::sort(out.begin(), out.end(), [](const LoopCandidate& a, const LoopCandidate& b) {
    return a.score != b.score ? a.score > b.score : a.id < b.id;
  });
  if (!out.empty()) {
    const double floor = options.min_ratio_to_best * out.front().score;
    out.erase(std::find_if(out.begin(), out.end(),
                           [&](const LoopCandidate& c) { return c.score < floor; }),
              out.end());
  }
  if (static_cast<int>(out.size()) > options.max_candidates)
    out.resize(static_cast<std::size_t>(options.max_candidates));
  return out;
}

std::vector<std::size_t> ConsistencyChecker::update(
    const std::vector<std::set<KeyframeId>>& groups) {
  std::vector<Group> current;
  std::vector<std::size_t> accepted;
  for (std::size_t i = 0; i < groups.size(); ++i) {
    int count = 1;
    for (const Group& prev : previous_) {
      const bool overlaps = std::any_of(prev.members.begin(), prev.members.end(),
                                        [&](KeyframeId id) { return groups[i].count(id) > 0; });
      if (overlaps) count = std::max(count, prev.count + 1);
    }
    current.push_back({groups[i], count});
    if (count >= required_) accepted.push_back(i);
  }
  previous_ = std::move(current);
  return accepted;
}

}  // namespace kestrel::loop
