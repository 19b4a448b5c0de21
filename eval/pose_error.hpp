#pragma once
// Per-pose errors of the absolute (APE) and relative (RPE) pose error, as evo's
// metrics.APE / metrics.RPE compute them on 4x4 matrices.
#include <vector>

#include "core/eigen_types.hpp"
#include "eval/pair_filter.hpp"

namespace kestrel::eval {

enum class PoseRelation {
  kTranslation,  // |t_E| in metres
  kAngleRad,     // rotation angle of E
  kAngleDeg,
  kFull,          // |E - I4|_F (evo "full transformation", unit-less)
  kRotationPart,  // |R_E - I3|_F
};

const char* relation_name(PoseRelation relation);  // evo's wording, e.g. "translation part"
const char* relation_unit(PoseRelation relation);  // "m", "rad", "deg" or ""

// evo's lie.se3_inverse: the rotation block is transposed, not inverted, exactly as evo does,
// which matters for KITTI's not-quite-orthonormal rotations.
Mat4 se3_inverse(const Mat4& pose);
// Rotation angle in [0, pi] through scipy's from_matrix (Shepperd's method, normalized).
double rotation_angle(const Mat3& rotation);

// APE: E_k = est_k^-1 ref_k (translation: |p_est - p_ref|). Both lists are already paired.
std::vector<double> ape_errors(const std::vector<Mat4>& ref, const std::vector<Mat4>& est,
                               PoseRelation relation);

// RPE: E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) with Q the reference, P the estimate.
std::vector<double> rpe_errors(const std::vector<Mat4>& ref, const std::vector<Mat4>& est,
                               const IdPairs& pairs, PoseRelation relation);

}  // namespace kestrel::eval
