#include "loop/loop_gate.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace kestrel::loop {

double path_length(const std::map<PoseId, SE3>& poses, PoseId from, PoseId to) {
  if (from > to) std::swap(from, to);
  auto it = poses.lower_bound(from);
  double length = 0.0;
  while (it != poses.end() && it->first < to) {
    const auto next = std::next(it);
    if (next == poses.end() || next->first > to) break;
    length += (next->second.translation() - it->second.translation()).norm();
    it = next;
  }
  return length;
}

LoopGateResult check_loop_drift(const std::map<PoseId, SE3>& poses, PoseId match, PoseId query,
                                const SE3& T_match_query, const LoopGateOptions& o) {
  LoopGateResult r;
  const auto m = poses.find(match);
  const auto q = poses.find(query);
  if (m == poses.end() || q == poses.end()) {
    r.plausible = r.rotation_plausible = false;
    return r;
  }
  const SE3 odometry = m->second.inverse() * q->second;
  const SE3 d = odometry.inverse() * T_match_query;
  r.path_m = path_length(poses, match, query);
  r.translation_m = d.translation().norm();
  r.rotation_rad = d.so3().angle();
  r.max_translation_m = o.translation_floor_m + o.translation_per_m * r.path_m;
  r.max_rotation_rad = o.rotation_floor_rad + o.rotation_per_m_rad * r.path_m;
  r.rotation_plausible =
      !o.enabled || (std::isfinite(r.rotation_rad) && r.rotation_rad <= r.max_rotation_rad);
  r.plausible =
      r.rotation_plausible &&
      (!o.enabled || (std::isfinite(r.translation_m) && r.translation_m <= r.max_translation_m));
  return r;
}

bool spans_restart(const std::set<PoseId>& restarts, PoseId a, PoseId b) {
  const auto r = restarts.upper_bound(std::min(a, b));
  return r != restarts.end() && *r <= std::max(a, b);
}

RestartSpan restart_span(const std::set<PoseId>& restarts, const std::set<PoseId>& blind, PoseId a,
                         PoseId b) {
  if (spans_restart(blind, a, b)) return RestartSpan::kBlind;
  return spans_restart(restarts, a, b) ? RestartSpan::kAttitudeHeld : RestartSpan::kNone;
}

bool accept_loop(const LoopGateResult& gate, RestartSpan span) {
  switch (span) {
    case RestartSpan::kNone:
      return gate.plausible;
    case RestartSpan::kAttitudeHeld:
      return gate.rotation_plausible;
    case RestartSpan::kBlind:
      return true;
  }
  return false;
}

}  // namespace kestrel::loop
