#pragma once
// Timestamp association between a reference and an estimated trajectory. Two rules exist in
// the wild and they pick different pairs, so both are here, each matching its tool exactly:
// evo's nearest-stamp rule and the TUM RGB-D benchmark's greedy unique matching.
#include <cstddef>
#include <vector>

namespace kestrel::eval {

// Index pairs (ref[k], est[k]), ordered as the tool orders them.
struct Matches {
  std::vector<std::size_t> ref;
  std::vector<std::size_t> est;

  std::size_t size() const { return ref.size(); }
  bool empty() const { return ref.empty(); }
};

// evo.core.sync.associate_trajectories: for each stamp of the shorter trajectory (the
// reference when both are as long) the first argmin |diff| in the longer one, kept when
// |diff| <= max_diff. `offset` is added to the estimate's stamps. A stamp of the longer
// trajectory may be used twice, as in evo.
Matches associate_evo(const std::vector<double>& ref_stamps, const std::vector<double>& est_stamps,
                      double max_diff, double offset = 0.0);

// associate.py of the TUM RGB-D tools (first = reference, second = estimate): every pair with
// |a - (b + offset)| < max_diff is a candidate; candidates sorted by (diff, a, b) are taken
// greedily with each stamp used once; the result is sorted by reference stamp. Of repeated
// stamps only the last pose counts (the script keys a dict by stamp).
Matches associate_tum(const std::vector<double>& ref_stamps, const std::vector<double>& est_stamps,
                      double max_diff, double offset = 0.0);

// KITTI-style pairing of pose i with pose i (both files list the same frames).
Matches associate_by_index(std::size_t count);

}  // namespace kestrel::eval
