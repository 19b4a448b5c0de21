#include "loop/edge_sigmas.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace kestrel::loop {
namespace {

void check(double value, bool may_be_zero, const char* field) {
  if (!std::isfinite(value) || value < 0.0 || (!may_be_zero && value == 0.0)) {
    throw std::invalid_argument(std::string("EdgeSigmas::") + field + " must be " +
                                (may_be_zero ? ">= 0" : "> 0") + " and finite, got " +
                                std::to_string(value));
  }
}

}  // namespace

void validate(const EdgeSigmas& s) {
  check(s.odometry_translation_floor_m, false, "odometry_translation_floor_m");
  check(s.odometry_translation_per_m, true, "odometry_translation_per_m");
  check(s.odometry_rotation_floor_rad, false, "odometry_rotation_floor_rad");
  check(s.odometry_rotation_per_m_rad, true, "odometry_rotation_per_m_rad");
  check(s.loop_translation_m, false, "loop_translation_m");
  check(s.loop_rotation_rad, false, "loop_rotation_rad");
}

PoseGraphEdge odometry_edge(PoseId from, PoseId to, const SE3& T_from_to, const EdgeSigmas& s) {
  validate(s);
  const double step = T_from_to.translation().norm();
  PoseGraphEdge e{from, to, T_from_to, EdgeKind::kSequential};
  e.sigma_translation = s.odometry_translation_floor_m + s.odometry_translation_per_m * step;
  e.sigma_rotation = s.odometry_rotation_floor_rad + s.odometry_rotation_per_m_rad * step;
  return e;
}

PoseGraphEdge loop_edge(PoseId from, PoseId to, const SE3& T_from_to, const EdgeSigmas& s) {
  validate(s);
  PoseGraphEdge e{from, to, T_from_to, EdgeKind::kLoop};
  e.sigma_translation = s.loop_translation_m;
  e.sigma_rotation = s.loop_rotation_rad;
  return e;
}

}  // namespace kestrel::loop
