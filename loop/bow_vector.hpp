#pragma once
// Bag-of-words image descriptions produced by loop/vocabulary.hpp. Plain data, no OpenCV.
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace kestrel::loop {

using WordId = std::uint32_t;
using NodeId = std::uint32_t;

// Sparse TF-IDF histogram, sorted by word id, weights summing to 1 (L1-normalized).
struct BowVector {
  std::vector<std::pair<WordId, double>> entries;

  bool empty() const { return entries.empty(); }
  std::size_t size() const { return entries.size(); }
};

// Direct index: for each vocabulary node at the chosen level, the features that fell under
// it. Guided matching compares only features that share a node.
using FeatureVector = std::map<NodeId, std::vector<int>>;

// DBoW2's L1 score of two L1-normalized vectors: 1 - |a - b|_1 / 2, in [0, 1] (1 = same).
double l1_score(const BowVector& a, const BowVector& b);

}  // namespace kestrel::loop
