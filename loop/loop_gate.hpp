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
  double translation_per_m = 0.05;       // of the path between the two keyframes
  double rotation_floor_rad = 0.01745;   // 1 degree
  double rotation_per_m_rad = 0.000873;  // 0.05 degree per metre of path
};

struct LoopGateResult {
  bool plausible = true;
  double path_m = 0.0;         // travelled between the two keyframes (odometry)
  double translation_m = 0.0;  // discrepancy between the measured and the odometry's pose
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

}  // namespace kestrel::loop
