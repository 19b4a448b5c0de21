#pragma once
// One-to-one pairs taken greedily, the highest score first: how a frame's boxes continue the
// tracks of the frames before (dynamic/parked_boxes, detect/box_coasting).
#include <algorithm>
#include <cstddef>
#include <vector>

namespace kestrel {

struct ScoredPair {
  double score = 0.0;
  std::size_t a = 0, b = 0;  // a < na, b < nb
};

// Per a (0 .. na - 1), the b it is paired with, or -1: pairs are taken by descending score, each
// a and each b at most once. `pairs` holds only the admissible ones (over a threshold, ...).
inline std::vector<int> greedy_pairs(std::vector<ScoredPair> pairs, std::size_t na,
                                     std::size_t nb) {
  std::sort(pairs.begin(), pairs.end(),
            [](const ScoredPair& x, const ScoredPair& y) { return x.score > y.score; });
  std::vector<int> b_of(na, -1);
  std::vector<bool> taken(nb, false);
  for (const ScoredPair& p : pairs) {
    if (b_of[p.a] >= 0 || taken[p.b]) continue;
    b_of[p.a] = static_cast<int>(p.b);
    taken[p.b] = true;
  }
  return b_of;
}

}  // namespace kestrel
