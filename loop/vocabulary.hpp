#pragma once
// A vocabulary tree over 256-bit ORB descriptors (Nistér & Stewénius; DBoW2's model):
// hierarchical k-majority clustering under Hamming distance, leaves are words with TF-IDF
// weights. Deterministic for a given seed and input order.
#include <cstdint>
#include <string>
#include <vector>

#include "loop/bow_vector.hpp"
#include "tracking/orb_descriptor.hpp"

namespace kestrel::loop {

using tracking::OrbDescriptor;

struct VocabularyOptions {
  int k = 10;      // branching factor
  int levels = 4;  // depth; at most k^levels words
  std::uint64_t seed = 42;
  int max_iterations = 15;  // k-majority iterations per node
};

class Vocabulary {
 public:
  struct Node {
    OrbDescriptor centroid;
    NodeId parent = 0;
    std::vector<NodeId> children;
    double weight = 0.0;     // IDF, leaves only
    std::int32_t word = -1;  // word id of a leaf, -1 for inner nodes
    int depth = 0;           // root 0
  };

  Vocabulary() = default;

  // Trains from the descriptors of several images (one vector per image; IDF counts images).
  static Vocabulary train(const std::vector<std::vector<OrbDescriptor>>& images,
                          const VocabularyOptions& options = {});

  // BoW vector of one image; with `features`, also the direct index at depth `direct_depth`
  // (1 = the root's children; clamped to the tree's depth).
  BowVector transform(const std::vector<OrbDescriptor>& descriptors,
                      FeatureVector* features = nullptr, int direct_depth = 2) const;
  // The word of one descriptor and, if asked, its ancestor at `direct_depth`.
  WordId word_of(const OrbDescriptor& d, NodeId* ancestor = nullptr, int direct_depth = 2) const;

  // Versioned binary file ("KVOC"); errors name the file.
  void save(const std::string& path) const;
  static Vocabulary load(const std::string& path);

  bool empty() const { return words_.empty(); }
  std::size_t num_words() const { return words_.size(); }
  std::size_t num_nodes() const { return nodes_.size(); }
  int k() const { return k_; }
  int levels() const { return levels_; }
  double word_weight(WordId w) const { return nodes_[words_[w]].weight; }
  const std::vector<Node>& nodes() const { return nodes_; }

  // Rebuilds a vocabulary from nodes (parents before children, node 0 the root); used by the
  // loader. Throws std::invalid_argument when the tree is malformed.
  static Vocabulary from_nodes(int k, int levels, std::vector<Node> nodes);

 private:
  int k_ = 0;
  int levels_ = 0;
  std::vector<Node> nodes_;    // node 0 is the root
  std::vector<NodeId> words_;  // word id -> node
};

}  // namespace kestrel::loop
