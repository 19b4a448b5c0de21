#pragma once
// Which pose pairs (i, j) the RPE compares: evo's filters.filter_pairs_by_index and
// filters.filter_pairs_by_path, reproduced rule for rule.
#include <cstddef>
#include <utility>
#include <vector>

#include "core/eigen_types.hpp"

namespace kestrel::eval {

using IdPairs = std::vector<std::pair<std::size_t, std::size_t>>;

// Consecutive: (0, d), (d, 2d), ...; all pairs: (i, i + d) for every i.
IdPairs filter_pairs_by_index(std::size_t count, std::size_t delta, bool all_pairs);

// Pairs `delta` metres of travelled path apart. Consecutive: the path is accumulated from the
// first pose and an index is kept (and the sum reset) each time it reaches delta; consecutive
// kept indices form the pairs (so pose 0 is not a pair start, as in evo). All pairs: for each i
// the j > i whose path length from i is nearest delta, kept if within `tol` of it.
IdPairs filter_pairs_by_path(const std::vector<Mat4>& poses, double delta, double tol,
                             bool all_pairs);

}  // namespace kestrel::eval
