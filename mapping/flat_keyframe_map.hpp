#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace kestrel::mapping {

using KeyframeId = std::int64_t;

// keyframe id -> int, sorted by keyframe id in one array: a map point's views (the feature
// index in each keyframe) and a keyframe's covisibility weights. It answers like the std::map
// it replaced (same order, same lookups). Every stage that grows with a revisited place walks
// these (keyframe culling, the local-BA gather, covisibility, the reference keyframe), and a
// tree's node-by-node walk was the largest single cost left on the tracking thread
// (std::_Rb_tree_increment, 9% of it on market at 100-240 s). Entries number tens to a hundred
// or two, so the array's shifting inserts cost less than the tree's allocations.
class FlatKeyframeMap {
 public:
  using value_type = std::pair<KeyframeId, int>;
  using iterator = std::vector<value_type>::iterator;
  using const_iterator = std::vector<value_type>::const_iterator;
  using const_reverse_iterator = std::vector<value_type>::const_reverse_iterator;

  FlatKeyframeMap() = default;
  FlatKeyframeMap(std::initializer_list<value_type> entries) {
    for (const auto& [kf, value] : entries) (*this)[kf] = value;
  }

  iterator begin() { return entries_.begin(); }
  iterator end() { return entries_.end(); }
  const_iterator begin() const { return entries_.begin(); }
  const_iterator end() const { return entries_.end(); }
  const_reverse_iterator rbegin() const { return entries_.rbegin(); }
  const_reverse_iterator rend() const { return entries_.rend(); }
  std::size_t size() const { return entries_.size(); }
  bool empty() const { return entries_.empty(); }

  iterator find(KeyframeId kf) {
    const auto it = lower_bound(kf);
    return it != entries_.end() && it->first == kf ? it : entries_.end();
  }
  const_iterator find(KeyframeId kf) const {
    const auto it = std::lower_bound(entries_.begin(), entries_.end(), kf, key_less);
    return it != entries_.end() && it->first == kf ? it : entries_.end();
  }
  bool contains(KeyframeId kf) const { return find(kf) != end(); }
  std::size_t count(KeyframeId kf) const { return contains(kf) ? 1 : 0; }

  // kf's value, inserted as 0 when kf has none yet (as std::map does).
  int& operator[](KeyframeId kf) {
    auto it = lower_bound(kf);
    if (it == entries_.end() || it->first != kf) it = entries_.insert(it, {kf, 0});
    return it->second;
  }
  // kf's value; std::out_of_range when kf has none.
  int at(KeyframeId kf) const {
    const auto it = find(kf);
    if (it == end()) throw std::out_of_range("no entry for keyframe " + std::to_string(kf));
    return it->second;
  }
  void clear() { entries_.clear(); }
  iterator erase(const_iterator it) { return entries_.erase(it); }
  std::size_t erase(KeyframeId kf) {
    const auto it = find(kf);
    if (it == entries_.end()) return 0;
    entries_.erase(it);
    return 1;
  }

  friend bool operator==(const FlatKeyframeMap&, const FlatKeyframeMap&) = default;

 private:
  static bool key_less(const value_type& v, KeyframeId kf) { return v.first < kf; }
  iterator lower_bound(KeyframeId kf) {
    return std::lower_bound(entries_.begin(), entries_.end(), kf, key_less);
  }

  std::vector<value_type> entries_;
};

}  // namespace kestrel::mapping
