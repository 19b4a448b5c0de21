#pragma once
// Where a mover is at time t: along its path at constant speed (loop, back and forth, or once),
// still before `start` and after `stop`; a spinning mover turns in place.
#include "sim/scenario.hpp"

namespace kestrel::sim {

struct MoverPose {
  Vec3 position = Vec3::Zero();  // on the ground (z of the path)
  double yaw = 0.0;              // heading, radians about z
  bool moving = false;
};

MoverPose mover_pose(const MoverSpec& spec, double t);

}  // namespace kestrel::sim
