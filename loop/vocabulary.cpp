#include "loop/vocabulary.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

namespace kestrel::loop {
namespace {

using tracking::hamming;

// Bitwise majority of the members: the k-majority centroid of binary descriptors.
OrbDescriptor majority(const std::vector<const OrbDescriptor*>& members) {
  std::array<int, 256> ones{};
  for (const OrbDescriptor* d : members) {
    for (int w = 0; w < 4; ++w) {
      std::uint64_t bits = d->words[static_cast<std::size_t>(w)];
      while (bits != 0) {
        ++ones[static_cast<std::size_t>(w * 64 + std::countr_zero(bits))];
        bits &= bits - 1;
      }
    }
  }
  OrbDescriptor c;
  const int half = static_cast<int>(members.size());
  for (int b = 0; b < 256; ++b) {
    if (2 * ones[static_cast<std::size_t>(b)] > half)
      c.words[static_cast<std::size_t>(b / 64)] |= std::uint64_t{1} << (b % 64);
  }
  return c;
}

// k-means++ seeding: each next centre drawn with probability proportional to the squared
// distance to the nearest centre so far.
std::vector<OrbDescriptor> seed_centres(const std::vector<const OrbDescriptor*>& data, int k,
                                        std::mt19937_64& rng) {
  std::vector<OrbDescriptor> centres;
  std::uniform_int_distribution<std::size_t> pick(0, data.size() - 1);
  centres.push_back(*data[pick(rng)]);
  std::vector<double> d2(data.size(), std::numeric_limits<double>::max());
  while (static_cast<int>(centres.size()) < k) {
    double total = 0.0;
    for (std::size_t i = 0; i < data.size(); ++i) {
      const double d = hamming(*data[i], centres.back());
      d2[i] = std::min(d2[i], d * d);
      total += d2[i];
    }
    if (total <= 0.0) break;  // fewer distinct descriptors than k
    std::uniform_real_distribution<double> u(0.0, total);
    double r = u(rng);
    std::size_t chosen = data.size() - 1;
    for (std::size_t i = 0; i < data.size(); ++i) {
      r -= d2[i];
      if (r <= 0.0 && d2[i] > 0.0) {
        chosen = i;
        break;
      }
    }
    centres.push_back(*data[chosen]);
  }
  return centres;
}

int nearest(const OrbDescriptor& d, const std::vector<OrbDescriptor>& centres) {
  int best = 0;
  int best_dist = std::numeric_limits<int>::max();
  for (std::size_t c = 0; c < centres.size(); ++c) {
    const int dist = hamming(d, centres[c]);
    if (dist < best_dist) {
      best_dist = dist;
      best = static_cast<int>(c);
    }
  }
  return best;
}

class Trainer {
 public:
  Trainer(const VocabularyOptions& options, std::vector<Vocabulary::Node>& nodes)
      : options_(options), nodes_(nodes), rng_(options.seed) {}

  void split(NodeId node, const std::vector<const OrbDescriptor*>& data) {
    const int depth = nodes_[node].depth;
    if (depth >= options_.levels || data.size() <= 1) return;
    std::vector<std::vector<const OrbDescriptor*>> clusters;
    std::vector<OrbDescriptor> centres;
    if (static_cast<int>(data.size()) <= options_.k) {
      for (const OrbDescriptor* d : data) {
        centres.push_back(*d);
        clusters.push_back({d});
      }
    } else {
      centres = seed_centres(data, options_.k, rng_);
      std::vector<int> assignment(data.size(), -1);
      for (int it = 0; it < options_.max_iterations; ++it) {
        bool changed = false;
        for (std::size_t i = 0; i < data.size(); ++i) {
          const int c = nearest(*data[i], centres);
          changed = changed || c != assignment[i];
          assignment[i] = c;
        }
        clusters.assign(centres.size(), {});
        for (std::size_t i = 0; i < data.size(); ++i)
          clusters[static_cast<std::size_t>(assignment[i])].push_back(data[i]);
        if (!changed && it > 0) break;
        // Empty clusters are dropped; the centres of the rest move to their majority.
        std::vector<OrbDescriptor> moved;
        std::vector<std::vector<const OrbDescriptor*>> kept;
        for (std::size_t c = 0; c < clusters.size(); ++c) {
          if (clusters[c].empty()) continue;
          moved.push_back(majority(clusters[c]));
          kept.push_back(std::move(clusters[c]));
        }
        if (moved.size() != centres.size()) std::fill(assignment.begin(), assignment.end(), -1);
        centres = std::move(moved);
        clusters = std::move(kept);
      }
    }
    for (std::size_t c = 0; c < centres.size(); ++c) {
      if (clusters[c].empty()) continue;
      Vocabulary::Node child;
      child.centroid = centres[c];
      child.parent = node;
      child.depth = depth + 1;
      const auto id = static_cast<NodeId>(nodes_.size());
      nodes_.push_back(child);
      nodes_[node].children.push_back(id);
    }
    // Children ids are contiguous from the first one; recurse after creating all of them so
    // that ids do not depend on recursion order within one parent.
    const std::vector<NodeId> children = nodes_[node].children;
    for (std::size_t c = 0, used = 0; c < centres.size(); ++c) {
      if (clusters[c].empty()) continue;
      split(children[used++], clusters[c]);
    }
  }

 private:
  const VocabularyOptions& options_;
  std::vector<Vocabulary::Node>& nodes_;
  std::mt19937_64 rng_;
};

}  // namespace

double l1_score(const BowVector& a, const BowVector& b) {
  // For L1-normalized vectors 1 - |a - b|_1 / 2 equals the sum of the common minima.
  double s = 0.0;
  auto ia = a.entries.begin();
  auto ib = b.entries.begin();
  while (ia != a.entries.end() && ib != b.entries.end()) {
    if (ia->first < ib->first) {
      ++ia;
    } else if (ib->first < ia->first) {
      ++ib;
    } else {
      s += std::min(ia->second, ib->second);
      ++ia;
      ++ib;
    }
  }
  return s;
}

Vocabulary Vocabulary::train(const std::vector<std::vector<OrbDescriptor>>& images,
                             const VocabularyOptions& options) {
  if (options.k < 2 || options.levels < 1)
    throw std::invalid_argument("vocabulary: k must be >= 2 and levels >= 1");
  std::vector<const OrbDescriptor*> all;
  for (const auto& image : images)
    for (const auto& d : image) all.push_back(&d);
  if (all.empty()) throw std::invalid_argument("vocabulary: no descriptors to train on");

  std::vector<Node> nodes(1);
  Trainer(options, nodes).split(0, all);
  Vocabulary voc = from_nodes(options.k, options.levels, std::move(nodes));

  // IDF: log(N / images containing the word); a word in every image carries no information.
  std::vector<int> images_with(voc.words_.size(), 0);
  std::vector<int> last_image(voc.words_.size(), -1);
  for (std::size_t i = 0; i < images.size(); ++i) {
    for (const auto& d : images[i]) {
      const WordId w = voc.word_of(d);
      if (last_image[w] != static_cast<int>(i)) {
        last_image[w] = static_cast<int>(i);
        ++images_with[w];
      }
    }
  }
  const double n = static_cast<double>(images.size());
  for (std::size_t w = 0; w < voc.words_.size(); ++w) {
    // A word never reached by its own training data (a majority centroid can pull the
    // descriptors elsewhere) is treated as seen once: rare, hence informative.
    voc.nodes_[voc.words_[w]].weight = std::log(n / std::max(images_with[w], 1));
  }
  return voc;
}

Vocabulary Vocabulary::from_nodes(int k, int levels, std::vector<Node> nodes) {
  if (nodes.empty()) throw std::invalid_argument("vocabulary has no root node");
  Vocabulary voc;
  voc.k_ = k;
  voc.levels_ = levels;
  for (auto& n : nodes) n.children.clear();
  for (std::size_t i = 1; i < nodes.size(); ++i) {
    if (nodes[i].parent >= i)
      throw std::invalid_argument("vocabulary node " + std::to_string(i) +
                                  " has a parent that does not precede it");
    nodes[nodes[i].parent].children.push_back(static_cast<NodeId>(i));
    nodes[i].depth = nodes[nodes[i].parent].depth + 1;
  }
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].children.empty() && i != 0) {
      nodes[i].word = static_cast<std::int32_t>(voc.words_.size());
      voc.words_.push_back(static_cast<NodeId>(i));
    } else {
      nodes[i].word = -1;
    }
  }
  voc.nodes_ = std::move(nodes);
  return voc;
}

WordId Vocabulary::word_of(const OrbDescriptor& d, NodeId* ancestor, int direct_depth) const {
  NodeId node = 0;
  if (ancestor) *ancestor = 0;
  while (!nodes_[node].children.empty()) {
    NodeId best = nodes_[node].children.front();
    int best_dist = std::numeric_limits<int>::max();
    for (NodeId c : nodes_[node].children) {
      const int dist = hamming(d, nodes_[c].centroid);
      if (dist < best_dist) {
        best_dist = dist;
        best = c;
      }
    }
    node = best;
    if (ancestor && nodes_[node].depth <= direct_depth) *ancestor = node;
  }
  return static_cast<WordId>(nodes_[node].word);
}

BowVector Vocabulary::transform(const std::vector<OrbDescriptor>& descriptors,
                                FeatureVector* features, int direct_depth) const {
  BowVector bow;
  if (features) features->clear();
  if (empty()) return bow;
  std::vector<std::pair<WordId, double>> raw;
  raw.reserve(descriptors.size());
  for (std::size_t i = 0; i < descriptors.size(); ++i) {
    NodeId ancestor = 0;
    const WordId w = word_of(descriptors[i], features ? &ancestor : nullptr, direct_depth);
    if (features) (*features)[ancestor].push_back(static_cast<int>(i));
    const double weight = word_weight(w);
    if (weight > 0.0) raw.emplace_back(w, weight);
  }
  std::sort(raw.begin(), raw.end());
  double total = 0.0;
  for (const auto& [w, weight] : raw) {
    if (!bow.entries.empty() && bow.entries.back().first == w)
      bow.entries.back().second += weight;
    else
      bow.entries.emplace_back(w, weight);
    total += weight;
  }
  if (total > 0.0)
    for (auto& e : bow.entries) e.second /= total;
  return bow;
}

}  // namespace kestrel::loop
