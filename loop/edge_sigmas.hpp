#pragma once
// How far each edge of the keyframe pose graph can be trusted. With one pair of sigmas for every
// edge, a loop measured by PnP (centimetres, a tenth of a degree) pulls as hard as the odometry
// between two keyframes a few centimetres apart (a millimetre): the graph then hands the loop's
// own error to the poses around it. Here the odometry's sigma grows with the step it spans, as
// drift does, and a loop gets the precision of a PnP pose.
#include "loop/pose_graph.hpp"

namespace kestrel::loop {

struct EdgeSigmas {
  // Odometry between consecutive keyframes: floor + share of the step's length.
  double odometry_translation_floor_m = 0.001;
  double odometry_translation_per_m = 0.01;
  double odometry_rotation_floor_rad = 0.0002;
  double odometry_rotation_per_m_rad = 0.001;
  // A verified loop (PnP on 30-100 inliers at 2-13 m). 1 cm fitted the most-similar-neighbour
  // rule's few loops as well; with the tens that the least similar closes, 3 cm did better:
  // over 22 draws 0.518 -> 0.489 m summed, cafe's four within 0.4 mm of no loops at all.
  double loop_translation_m = 0.03;
  double loop_rotation_rad = 0.002;
};

// Throws std::invalid_argument naming the field when a sigma would not be positive and finite
// (the per-metre shares may be 0). The System checks its options with it before its threads
// start, so a bad value is reported to the caller, not thrown in the loop-closing thread.
void validate(const EdgeSigmas& sigmas);

// Both validate `sigmas` first.
PoseGraphEdge odometry_edge(PoseId from, PoseId to, const SE3& T_from_to,
                            const EdgeSigmas& sigmas = {});
PoseGraphEdge loop_edge(PoseId from, PoseId to, const SE3& T_from_to,
                        const EdgeSigmas& sigmas = {});

}  // namespace kestrel::loop
