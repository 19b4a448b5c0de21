#include "eval/association.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

namespace kestrel::eval {
namespace {

// np.argmin(np.abs(shifted - s)): the first index of the smallest difference.
std::size_t nearest_index(const std::vector<double>& shifted, bool sorted, double s) {
  if (!sorted) {
    std::size_t best = 0;
    for (std::size_t k = 1; k < shifted.size(); ++k) {
      if (std::abs(shifted[k] - s) < std::abs(shifted[best] - s)) best = k;
    }
    return best;
  }
  // |x - s| falls then rises along a sorted array (rounding is monotonic too), so the minimum
  // sits beside the insertion point; ties go to the lower index as argmin does.
  const auto it = std::lower_bound(shifted.begin(), shifted.end(), s);
  std::size_t k = static_cast<std::size_t>(it - shifted.begin());
  std::size_t best = 0;
  if (k == shifted.size()) {
    best = k - 1;
  } else if (k == 0) {
    best = 0;
  } else {
    best = std::abs(shifted[k - 1] - s) <= std::abs(shifted[k] - s) ? k - 1 : k;
  }
  while (best > 0 && shifted[best - 1] == shifted[best]) --best;
  return best;
}

// associate.py reads each file into a dict keyed by stamp, so of repeated stamps only the last
// line counts.
std::vector<bool> last_of_each_stamp(const std::vector<double>& stamps) {
  std::map<double, std::size_t> last;
  for (std::size_t k = 0; k < stamps.size(); ++k) last[stamps[k]] = k;
  std::vector<bool> keep(stamps.size(), false);
  for (const auto& [stamp, k] : last) keep[k] = true;
  return keep;
}

}  // namespace

Matches associate_evo(const std::vector<double>& ref_stamps, const std::vector<double>& est_stamps,
                      double max_diff, double offset) {
  Matches matches;
  if (ref_stamps.empty() || est_stamps.empty()) return matches;
  const bool est_longer = est_stamps.size() > ref_stamps.size();
  const std::vector<double>& shorter = est_longer ? ref_stamps : est_stamps;
  const std::vector<double>& longer = est_longer ? est_stamps : ref_stamps;
  // evo shifts the longer list: by +offset when it is the estimate, by -offset otherwise.
  const double shift = est_longer ? offset : -offset;
  std::vector<double> shifted(longer.size());
  for (std::size_t k = 0; k < longer.size(); ++k) shifted[k] = longer[k] + shift;
  const bool sorted = std::is_sorted(shifted.begin(), shifted.end());

  for (std::size_t i = 0; i < shorter.size(); ++i) {
    const std::size_t j = nearest_index(shifted, sorted, shorter[i]);
    if (std::abs(shifted[j] - shorter[i]) <= max_diff) {
      matches.ref.push_back(est_longer ? i : j);
      matches.est.push_back(est_longer ? j : i);
    }
  }
  return matches;
}

Matches associate_tum(const std::vector<double>& ref_stamps, const std::vector<double>& est_stamps,
                      double max_diff, double offset) {
  std::vector<double> shifted(est_stamps.size());
  for (std::size_t k = 0; k < est_stamps.size(); ++k) shifted[k] = est_stamps[k] + offset;
  std::vector<std::size_t> order(shifted.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return shifted[a] < shifted[b]; });

  // Candidates (diff, a, b); the window search only prunes, the test is the tool's own.
  struct Candidate {
    double diff;
    double a;
    double b;
    std::size_t i;
    std::size_t j;
  };
  const std::vector<bool> ref_valid = last_of_each_stamp(ref_stamps);
  const std::vector<bool> est_valid = last_of_each_stamp(est_stamps);
  std::vector<Candidate> candidates;
  for (std::size_t i = 0; i < ref_stamps.size(); ++i) {
    if (!ref_valid[i]) continue;
    const double a = ref_stamps[i];
    auto it = std::lower_bound(order.begin(), order.end(), a - max_diff,
                               [&](std::size_t k, double v) { return shifted[k] < v; });
    if (it != order.begin()) --it;  // one step back guards against rounding at the edge
    for (; it != order.end(); ++it) {
      const std::size_t j = *it;
      if (shifted[j] > a + max_diff && std::abs(a - shifted[j]) >= max_diff) break;
      const double diff = std::abs(a - shifted[j]);
      if (diff < max_diff && est_valid[j]) candidates.push_back({diff, a, est_stamps[j], i, j});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& l, const Candidate& r) {
    return std::tie(l.diff, l.a, l.b, l.i, l.j) < std::tie(r.diff, r.a, r.b, r.i, r.j);
  });

  std::vector<bool> ref_used(ref_stamps.size(), false);
  std::vector<bool> est_used(est_stamps.size(), false);
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (const Candidate& c : candidates) {
    if (ref_used[c.i] || est_used[c.j]) continue;
    ref_used[c.i] = true;
    est_used[c.j] = true;
    pairs.emplace_back(c.i, c.j);
  }
  // matches.sort() orders by (a, b); with each a used once that is the order of a.
  std::sort(pairs.begin(), pairs.end(), [&](const auto& l, const auto& r) {
    return std::tie(ref_stamps[l.first], est_stamps[l.second], l.first) <
           std::tie(ref_stamps[r.first], est_stamps[r.second], r.first);
  });
  Matches matches;
  for (const auto& [i, j] : pairs) {
    matches.ref.push_back(i);
    matches.est.push_back(j);
  }
  return matches;
}

Matches associate_by_index(std::size_t count) {
  Matches matches;
  matches.ref.resize(count);
  matches.est.resize(count);
  for (std::size_t k = 0; k < count; ++k) matches.ref[k] = matches.est[k] = k;
  return matches;
}

}  // namespace kestrel::eval
