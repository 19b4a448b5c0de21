#pragma once
// Inverted index word -> keyframes for place recognition (DBoW2 / ORB-SLAM), with
// ORB-SLAM's normalisation by the query's own neighbours and a temporal-consistency check.
#include <cstdint>
#include <set>
#include <unordered_map>
#include <vector>

#include "loop/bow_vector.hpp"

namespace kestrel::loop {

using KeyframeId = std::int64_t;

struct LoopCandidate {
  KeyframeId id = -1;
  double score = 0.0;       // raw L1 score against the query
  double normalized = 0.0;  // score / the query's score against its own neighbours (see options)
};

struct KeyframeDatabaseOptions {
  double min_score = 0.02;  // raw L1 score below which a keyframe is never a candidate
  // Of a neighbour score: a loop must look at least as much like the query as the query's own
  // neighbours do. Repetitive texture (tiles, bricks) raises every score alike; this ratio is
  // what separates a revisit from it.
  double min_normalized = 1.0;
  // Which neighbour: the least similar (ORB-SLAM's rule: as much as the weakest covisible
  // keyframe) or the most similar. The most similar asked a revisit to beat the query's best
  // neighbour, which a crowd walking through the view rarely let it: market closed 5-7 loops
  // where its still twin closed 20-26. Least similar, with the loop gate at 2% of the path and
  // loop/edge_sigmas.hpp's weights: 39-53 (README "Loop closing").
  bool least_similar_neighbour = true;
  // Of the best candidate's score (ORB-SLAM keeps groups above 0.75 of the best): a clear
  // winner suppresses the look-alikes.
  double min_ratio_to_best = 0.75;
  int max_candidates = 10;
};

class KeyframeDatabase {
 public:
  explicit KeyframeDatabase(const KeyframeDatabaseOptions& options = {}) : options_(options) {}

  void add(KeyframeId id, BowVector bow);
  void erase(KeyframeId id);
  void clear();
  const BowVector* bow(KeyframeId id) const;
  std::size_t size() const { return bows_.size(); }

  // Keyframes sharing words with `bow`, excluding `exclude` (the query itself, its covisible
  // and recent keyframes), scored by l1_score. `neighbours` (keyframes in the database that
  // see the same place as the query) set the normaliser: their best score against the query.
  // With no neighbour scored, normalized == score. Best first, at most max_candidates.
  std::vector<LoopCandidate> query(const BowVector& bow, const std::vector<KeyframeId>& neighbours,
                                   const std::set<KeyframeId>& exclude) const {
    return query(bow, neighbours, exclude, options_);
  }
  // The same with other thresholds (relocalisation has no neighbours to normalise by).
  std::vector<LoopCandidate> query(const BowVector& bow, const std::vector<KeyframeId>& neighbours,
                                   const std::set<KeyframeId>& exclude,
                                   const KeyframeDatabaseOptions& options) const;

  const KeyframeDatabaseOptions& options() const { return options_; }

 private:
  KeyframeDatabaseOptions options_;
  std::unordered_map<KeyframeId, BowVector> bows_;
  std::unordered_map<WordId, std::vector<KeyframeId>> inverted_;
};

// ORB-SLAM's temporal consistency: a candidate's group (the candidate and its covisible
// keyframes) must overlap a group that was consistent in the previous query; a loop is
// accepted once a chain of `required` consecutive queries has formed.
class ConsistencyChecker {
 public:
  explicit ConsistencyChecker(int required = 3) : required_(required) {}

  // Feeds the groups of one query (one per candidate, same order). Returns the indices of
  // candidates whose chain reached `required` consecutive queries.
  std::vector<std::size_t> update(const std::vector<std::set<KeyframeId>>& groups);
  // Forgets every chain (after a loop was closed, or when a query had no candidate).
  void reset() { previous_.clear(); }

 private:
  struct Group {
    std::set<KeyframeId> members;
    int count = 0;  // consecutive queries the chain has lasted
  };
  int required_;
  std::vector<Group> previous_;
};

}  // namespace kestrel::loop
