#pragma once
// Aligning an estimated trajectory to the reference before APE, as evo does it: Umeyama on the
// paired positions, then the estimate is scaled (Sim(3)) and left-multiplied by [R t].
#include <optional>
#include <vector>

#include "core/eigen_types.hpp"
#include "eval/umeyama.hpp"

namespace kestrel::eval {

enum class Alignment { kNone, kSe3, kSim3 };

const char* alignment_name(Alignment alignment);  // "none", "SE(3)", "Sim(3)"

// Umeyama of est positions onto ref positions; nullopt when degenerate (see umeyama.hpp).
std::optional<Similarity> estimate_alignment(const std::vector<Mat4>& ref,
                                             const std::vector<Mat4>& est, bool with_scale);

// evo's PosePath3D.scale then .transform: t *= s, then T <- [R t] T.
void apply_alignment(std::vector<Mat4>& est, const Similarity& similarity);

// evo's align_origin: est <- (ref_0 est_0^-1) est, so both start at the same pose.
Mat4 align_origin(std::vector<Mat4>& est, const std::vector<Mat4>& ref);

}  // namespace kestrel::eval
