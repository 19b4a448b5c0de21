#pragma once
// Trajectory files: TUM (`t tx ty tz qx qy qz qw`), EuRoC ground-truth csv (`t[ns], p xyz,
// q wxyz, ...`) and KITTI poses (3x4 row-major, stamps from an optional times file). The format
// is detected from the content, so users never have to say which one they hold.
#include <string>
#include <vector>

#include "core/eigen_types.hpp"
#include "core/trajectory.hpp"

namespace kestrel::io {

enum class TrajectoryFormat { kTum, kEuroc, kKitti };

const char* format_name(TrajectoryFormat format);

// What a file literally holds, as 4x4 matrices built the way evo builds them. Evaluation works
// on these so that its figures match evo's to the last digits: KITTI rotation blocks are kept as
// written (7 significant digits, so not quite orthonormal; re-orthonormalizing them moves RPE by
// ~1e-6 relative), and quaternions become matrices through the same formula evo uses.
struct PoseSeries {
  TrajectoryFormat format = TrajectoryFormat::kTum;
  bool stamped = true;         // false: KITTI without a times file, stamps are 0, 1, 2, ...
  std::vector<double> stamps;  // seconds, never decreasing (repeats occur in real data)
  std::vector<Mat4> poses;     // T_w_body

  std::size_t size() const { return poses.size(); }
};

// Parses text in the given format; `name` is what errors call the file.
PoseSeries parse_pose_series(const std::string& text, const std::string& name,
                             TrajectoryFormat format);
// Parses text, detecting the format from the first data row.
PoseSeries parse_pose_series(const std::string& text, const std::string& name);
// Reads a file, detecting its format. `times_path` (KITTI only) gives one stamp per pose.
PoseSeries read_pose_series(const std::string& path, const std::string& times_path = "");

// The same files as kestrel::Trajectory (rotations re-orthonormalized into unit quaternions).
Trajectory to_trajectory(const PoseSeries& series);
// ... and back, for evaluating a trajectory the system made (stamped, TUM-like).
PoseSeries to_pose_series(const Trajectory& trajectory);
Trajectory read_trajectory(const std::string& path, const std::string& times_path = "");
Trajectory parse_trajectory(const std::string& text, const std::string& name);

// TUM text with shortest round-trip decimals, so reading it back gives identical doubles.
std::string format_tum(const Trajectory& trajectory);
void write_tum(const std::string& path, const Trajectory& trajectory);

// evo's quaternion -> rotation formula (transformations.quaternion_matrix): it normalizes the
// quaternion inside the formula; matching it keeps APE/RPE on TUM files bit-comparable with evo.
Mat4 pose_matrix(double tx, double ty, double tz, double qw, double qx, double qy, double qz);

}  // namespace kestrel::io
