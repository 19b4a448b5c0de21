#pragma once
// Whether a verified loop agrees with the drift odometry can have built up since the place was
// last seen. Geometric verification (PnP on 30+ inliers) still passes look-alike places and
// poses bent by a few matches on movers or repeated texture: over three cafe draws and one more
// run, 6 of 12 verified loops were 0.16-0.64 m and 1.8-11 degrees off the truth while the odometry
// between the two keyframes had drifted by millimetres, and each one, as an edge of the pose graph,
// bent the whole trajectory (cafe seed 4: APE 0.007 m without loops, 0.087 m with them). A true
// loop's discrepancy with the odometry is the drift itself, which grows with the path travelled
// (measured: ugv-loop 0.2 m and 0.7 degrees over 70 m, uav-zigzag up to 1.0 m and 3.3 degrees
// over 108 m), so a loop is kept when its discrepancy lies within a floor plus a share of the
// path between the two keyframes.
#include <map>
#include <set>

#include "core/se3.hpp"
#include "loop/pose_graph.hpp"

namespace kestrel::loop {

struct LoopGateOptions {
  bool enabled = true;
  double translation_floor_m = 0.05;
  // Of the path between the two keyframes: twice the worst drift measured above. At 5% a
  // look-alike loop on ugv-loop (23.8 s back to 3.0 s, 56 of 64 matches, 2.45 m off the
  // odometry over 72.9 m) passed once place recognition asked less of a candidate
  // (KeyframeDatabaseOptions::least_similar_neighbour) and bent the map: APE 0.020 -> 0.474 m.
  double translation_per_m = 0.02;
  double rotation_floor_rad = 0.01745;   // 1 degree
  double rotation_per_m_rad = 0.000873;  // 0.05 degree per metre of path
};

struct LoopGateResult {
  bool plausible = true;
  bool rotation_plausible = true;  // the rotation alone agrees (implied by plausible)
  double path_m = 0.0;             // travelled between the two keyframes (odometry)
  double translation_m = 0.0;      // discrepancy between the measured and the odometry's pose
  double rotation_rad = 0.0;
  double max_translation_m = 0.0;
  double max_rotation_rad = 0.0;
};

// Length of the path through the keyframe poses (T_w_c, in id order) from `from` to `to`.
double path_length(const std::map<PoseId, SE3>& poses, PoseId from, PoseId to);

// `poses`: the odometry's keyframe poses T_w_c (not yet corrected by any loop);
// `T_match_query`: the loop's measured pose of the query camera in the matched keyframe's frame.
// A pose missing from `poses` makes the loop implausible.
LoopGateResult check_loop_drift(const std::map<PoseId, SE3>& poses, PoseId match, PoseId query,
                                const SE3& T_match_query, const LoopGateOptions& options = {});

// Whether a keyframe in (min(a, b), max(a, b)] restarted the local map after a lost track. Across
// such a restart the odometry does not know how far the body went unseen, so it cannot judge a
// loop: only the loop can say.
bool spans_restart(const std::set<PoseId>& restarts, PoseId a, PoseId b);

// What the odometry between two keyframes knows across restarts of the local map.
enum class RestartSpan {
  kNone,          // no restart between them: the odometry is whole
  kAttitudeHeld,  // restarts, each at an attitude the IMU held: the position is unknown
  kBlind,         // a restart with nothing held: neither the position nor the attitude is known
};
// `restarts`: every keyframe that restarted the local map; `blind`: those of them where
// nothing held the attitude.
RestartSpan restart_span(const std::set<PoseId>& restarts, const std::set<PoseId>& blind, PoseId a,
                         PoseId b);

// Whether a loop goes into the pose graph: it agrees with the odometry; or the odometry cannot
// judge it, a restart in between. With the IMU the attitude survives a restart, so the
// rotation still has to agree: in a dark corridor's turn, two keyframes a second apart across a
// bridged loss matched 36 and 26 degrees off the gyro's turn, and the pose graph bent the rest
// of the run by that much (corridor-dark: 4.95 m APE).
bool accept_loop(const LoopGateResult& gate, RestartSpan span);

}  // namespace kestrel::loop
