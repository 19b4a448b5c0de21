#include "eval/object_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace kestrel::eval {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

ObjectScores score_objects(const std::vector<ObjectBox>& truth,
                           const std::vector<ObjectBox>& reported) {
  ObjectScores s;
  s.truth = static_cast<int>(truth.size());
  s.reported = static_cast<int>(reported.size());
  struct Pair {
    double d;
    std::size_t t, r;
  };
  std::vector<Pair> pairs;
  for (std::size_t t = 0; t < truth.size(); ++t)
    for (std::size_t r = 0; r < reported.size(); ++r) {
      const double d = (truth[t].center - reported[r].center).norm();
      const double gate = std::min(0.5, std::max(0.15, 0.5 * truth[t].size.maxCoeff()));
      // Same-label pairs first; a wrong label matches only what nothing else claims.
      const double penalty = truth[t].label == reported[r].label ? 0.0 : 10.0;
      if (d < gate) pairs.push_back({d + penalty, t, r});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d < b.d; });
  std::vector<bool> t_used(truth.size(), false), r_used(reported.size(), false);
  std::vector<double> centre_err, size_err;
  std::vector<std::string> status(truth.size());
  for (const Pair& p : pairs) {
    if (t_used[p.t] || r_used[p.r]) continue;
    t_used[p.t] = r_used[p.r] = true;
    ++s.matched;
    const ObjectBox& w = truth[p.t];
    const ObjectBox& e = reported[p.r];
    s.label_correct += w.label == e.label;
    const double dist = (w.center - e.center).norm();
    centre_err.push_back(dist);
    // Footprint axes compared sorted: a square's principal axis is arbitrary.
    const double tw = std::max(w.size.x(), w.size.y()), td = std::min(w.size.x(), w.size.y());
    const double ew = std::max(e.size.x(), e.size.y()), ed = std::min(e.size.x(), e.size.y());
    size_err.push_back(std::abs(ew - tw) / tw);
    size_err.push_back(std::abs(ed - td) / td);
    size_err.push_back(std::abs(e.size.z() - w.size.z()) / w.size.z());
    char buf[320];
    std::snprintf(buf, sizeof(buf),
                  "%-13s centre err %.3f m (%+.2f, %+.2f, %+.2f), size %.2fx%.2fx%.2f (truth "
                  "%.2fx%.2fx%.2f), %d obs%s%s",
                  w.label.c_str(), dist, e.center.x() - w.center.x(), e.center.y() - w.center.y(),
                  e.center.z() - w.center.z(), ew, ed, e.size.z(), tw, td, w.size.z(),
                  e.observations, w.label == e.label ? "" : ", reported as ",
                  w.label == e.label ? "" : e.label.c_str());
    status[p.t] = buf;
  }
  for (std::size_t t = 0; t < truth.size(); ++t)
    s.lines.push_back(t_used[t] ? status[t] : truth[t].label + " missed");
  for (std::size_t r = 0; r < reported.size(); ++r)
    if (!r_used[r]) {
      char buf[160];
      const ObjectBox& b = reported[r];
      std::snprintf(buf, sizeof(buf),
                    "extra %s at (%.2f, %.2f, %.2f), size %.2fx%.2fx%.2f, yaw %.0f deg, %d obs",
                    b.label.c_str(), b.center.x(), b.center.y(), b.center.z(), b.size.x(),
                    b.size.y(), b.size.z(), b.yaw * 180 / std::numbers::pi, b.observations);
      s.lines.push_back(buf);
    }
  s.recall = s.truth > 0 ? static_cast<double>(s.matched) / s.truth : 0.0;
  s.precision = s.reported > 0 ? static_cast<double>(s.matched) / s.reported : 0.0;
  s.class_correct = s.matched > 0 ? static_cast<double>(s.label_correct) / s.matched : 0.0;
  s.center_error_median = median(centre_err);
  s.size_error_median = median(size_err);
  return s;
}

}  // namespace kestrel::eval
