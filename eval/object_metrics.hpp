#pragma once
// Object-map accuracy against a world's ground-truth objects: one-to-one matching by centre
// distance, then recall, precision (duplicates count against it), class accuracy and the
// median centre and size errors of the matches. Shared by the tests and `kestrel bench`.
#include <string>
#include <vector>

#include "core/eigen_types.hpp"

namespace kestrel::eval {

// An upright box in the world frame; size is (along yaw, across, vertical).
struct ObjectBox {
  std::string label;
  Vec3 center = Vec3::Zero();
  Vec3 size = Vec3::Zero();
  double yaw = 0.0;
  int observations = 0;  // reported objects only, for the lines
};

struct ObjectScores {
  int truth = 0;
  int reported = 0;
  int matched = 0;  // reported objects matched to a distinct truth object (any label)
  int label_correct = 0;
  double recall = 0, precision = 0, class_correct = 0;
  double center_error_median = 0;  // metres, over matches
  double size_error_median = 0;    // relative, over matches and axes
  std::vector<std::string> lines;  // one per truth object, then one per unmatched report
};

// Greedy matching, nearest pairs first, same-label pairs before any cross-label pair; a match
// must lie within half the truth's largest side, clamped to 0.15..0.5 m.
ObjectScores score_objects(const std::vector<ObjectBox>& truth,
                           const std::vector<ObjectBox>& reported);

}  // namespace kestrel::eval
