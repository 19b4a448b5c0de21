#include "mapping/flat_keyframe_map.hpp"

#include <gtest/gtest.h>
#include <rapidcheck.h>

#include <map>
#include <stdexcept>
#include <vector>

namespace kestrel::mapping {
namespace {

std::vector<std::pair<KeyframeId, int>> entries(const FlatKeyframeMap& m) {
  return {m.begin(), m.end()};
}
std::vector<std::pair<KeyframeId, int>> entries(const std::map<KeyframeId, int>& m) {
  return {m.begin(), m.end()};
}

// Any sequence of inserts, overwrites and erasures leaves the same entries, in the same order,
// as a std::map given the same operations: the flat map replaced one there, and the map's
// results (descriptors from the newest views, the oldest view as reference) depend on order.
TEST(FlatKeyframeMap, BehavesAsAStdMapUnderAnySequenceOfEdits) {
  EXPECT_TRUE(rc::check("same entries as std::map", [] {
    const auto ops = *rc::gen::container<std::vector<std::tuple<int, int, int>>>(rc::gen::tuple(
        rc::gen::inRange(0, 4), rc::gen::inRange(-3, 40), rc::gen::arbitrary<int>()));
    FlatKeyframeMap flat;
    std::map<KeyframeId, int> model;
    for (const auto& [op, key, value] : ops) {
      switch (op) {
        case 0:
          flat[key] = value;
          model[key] = value;
          break;
        case 1:
          RC_ASSERT(flat.erase(key) == model.erase(key));
          break;
        case 2:
          if (auto it = flat.find(key); it != flat.end()) flat.erase(it);
          model.erase(key);
          break;
        default:
          RC_ASSERT(flat.contains(key) == model.contains(key));
          RC_ASSERT(flat.count(key) == model.count(key));
          if (model.contains(key)) RC_ASSERT(flat.at(key) == model.at(key));
          break;
      }
      RC_ASSERT(flat.size() == model.size());
    }
    RC_ASSERT(entries(flat) == entries(model));
    using Entries = std::vector<std::pair<KeyframeId, int>>;
    RC_ASSERT(Entries(flat.rbegin(), flat.rend()) == Entries(model.rbegin(), model.rend()));
  }));
}

TEST(FlatKeyframeMap, ReadsAsAMapDoes) {
  FlatKeyframeMap m{{7, 1}, {3, 2}, {5, 3}};
  EXPECT_EQ(entries(m), (std::vector<std::pair<KeyframeId, int>>{{3, 2}, {5, 3}, {7, 1}}));
  EXPECT_EQ(m[4], 0);  // inserted as std::map would
  EXPECT_EQ(m.size(), 4u);
  EXPECT_THROW((void)m.at(6), std::out_of_range);
  EXPECT_EQ(m.find(6), m.end());
  m.clear();
  EXPECT_TRUE(m.empty());
  EXPECT_EQ(m, FlatKeyframeMap{});
}

}  // namespace
}  // namespace kestrel::mapping
