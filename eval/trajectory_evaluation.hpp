#pragma once
// APE and RPE of an estimated trajectory against a reference, end to end: association,
// alignment, per-pose errors, statistics — the steps evo_ape / evo_rpe (and the TUM
// benchmark's evaluate_ate.py) take, in the same order.
#include <string>
#include <vector>

#include "eval/alignment.hpp"
#include "eval/association.hpp"
#include "eval/error_statistics.hpp"
#include "eval/pose_error.hpp"
#include "io/trajectory_io.hpp"

namespace kestrel::eval {

enum class AssociationMethod { kEvo, kTum };

// evo_ape's and associate.py's defaults differ; so does ours, by method.
constexpr double kEvoMaxDiff = 0.01;
constexpr double kTumMaxDiff = 0.02;

struct AssociationOptions {
  AssociationMethod method = AssociationMethod::kEvo;
  double max_diff = kEvoMaxDiff;  // seconds
  double offset = 0.0;            // added to the estimate's stamps
};

struct ApeOptions {
  AssociationOptions association;
  Alignment alignment = Alignment::kNone;
  bool align_origin = false;  // used only without Umeyama alignment, as in evo
  PoseRelation relation = PoseRelation::kTranslation;
};

enum class DeltaUnit { kFrames, kMeters };

struct RpeOptions {
  AssociationOptions association;
  Alignment alignment = Alignment::kNone;
  bool align_origin = false;
  PoseRelation relation = PoseRelation::kTranslation;
  double delta = 1.0;
  DeltaUnit unit = DeltaUnit::kFrames;
  bool all_pairs = false;
  double rel_tol = 0.1;  // all-pairs path tolerance, relative to delta (evo's rel_delta_tol)
};

struct Evaluation {
  std::string title;  // evo-style, e.g. "APE w.r.t. translation part (m)"
  ErrorStatistics stats;
  std::vector<double> errors;
  std::vector<std::size_t> error_pose;  // for each error, the associated pose it belongs to
  std::vector<Mat4> ref;                // associated reference poses
  std::vector<Mat4> est;                // associated estimate poses, after alignment
  std::vector<double> stamps;           // reference stamps of the associated poses
  Similarity alignment;                 // identity unless aligned
};

// Pairs two series: by time when both have stamps, else pose i with pose i (KITTI), which needs
// equal lengths. Throws kestrel::Error when the lengths differ or nothing matches.
Matches associate(const io::PoseSeries& ref, const io::PoseSeries& est,
                  const AssociationOptions& options);

Evaluation evaluate_ape(const io::PoseSeries& ref, const io::PoseSeries& est,
                        const ApeOptions& options);
Evaluation evaluate_rpe(const io::PoseSeries& ref, const io::PoseSeries& est,
                        const RpeOptions& options);

}  // namespace kestrel::eval
