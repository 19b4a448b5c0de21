#include "eval/trajectory_evaluation.hpp"

#include <cmath>
#include <sstream>

#include "core/error.hpp"

namespace kestrel::eval {
namespace {

std::string number_text(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// Associates, then aligns the estimate; fills everything of Evaluation but the errors.
Evaluation prepare(const io::PoseSeries& ref, const io::PoseSeries& est,
                   const AssociationOptions& association, Alignment alignment, bool origin) {
  const Matches matches = associate(ref, est, association);
  Evaluation ev;
  ev.ref.reserve(matches.size());
  ev.est.reserve(matches.size());
  for (std::size_t k = 0; k < matches.size(); ++k) {
    ev.ref.push_back(ref.poses[matches.ref[k]]);
    ev.est.push_back(est.poses[matches.est[k]]);
    ev.stamps.push_back(ref.stamps[matches.ref[k]]);
  }
  if (alignment != Alignment::kNone) {
    const auto similarity = estimate_alignment(ev.ref, ev.est, alignment == Alignment::kSim3);
    if (!similarity) {
      throw Error("Umeyama alignment is not possible: the " + std::to_string(matches.size()) +
                  " associated positions are degenerate (need 3 non-collinear)");
    }
    ev.alignment = *similarity;
    apply_alignment(ev.est, ev.alignment);
  } else if (origin) {
    align_origin(ev.est, ev.ref);
  }
  return ev;
}

std::string alignment_suffix(Alignment alignment, bool origin) {
  switch (alignment) {
    case Alignment::kSe3:
      return "\n(with SE(3) Umeyama alignment)";
    case Alignment::kSim3:
      return "\n(with Sim(3) Umeyama alignment)";
    case Alignment::kNone:
      break;
  }
  return origin ? "\n(with origin alignment)" : "\n(not aligned)";
}

std::string relation_title(PoseRelation relation) {
  std::string title = relation_name(relation);
  const std::string unit = relation_unit(relation);
  title += unit.empty() ? " (unit-less)" : " (" + unit + ")";
  return title;
}

}  // namespace

Matches associate(const io::PoseSeries& ref, const io::PoseSeries& est,
                  const AssociationOptions& options) {
  if (ref.size() == 0 || est.size() == 0) throw Error("cannot evaluate an empty trajectory");
  Matches matches;
  if (ref.stamped && est.stamped) {
    matches = options.method == AssociationMethod::kTum
                  ? associate_tum(ref.stamps, est.stamps, options.max_diff, options.offset)
                  : associate_evo(ref.stamps, est.stamps, options.max_diff, options.offset);
    if (matches.empty()) {
      throw Error(
          "found no matching timestamps between reference and estimate with max. time "
          "diff " +
          number_text(options.max_diff) + " s and offset " + number_text(options.offset) + " s");
    }
  } else {
    if (ref.size() != est.size()) {
      throw Error(
          "without timestamps poses are paired by index, which needs equal lengths: "
          "reference has " +
          std::to_string(ref.size()) + " poses, estimate " + std::to_string(est.size()) +
          " (give --ref-times/--est-times)");
    }
    matches = associate_by_index(ref.size());
  }
  return matches;
}

Evaluation evaluate_ape(const io::PoseSeries& ref, const io::PoseSeries& est,
                        const ApeOptions& options) {
  Evaluation ev = prepare(ref, est, options.association, options.alignment, options.align_origin);
  ev.errors = ape_errors(ev.ref, ev.est, options.relation);
  ev.error_pose.resize(ev.errors.size());
  for (std::size_t k = 0; k < ev.errors.size(); ++k) ev.error_pose[k] = k;
  ev.stats = compute_statistics(ev.errors);
  ev.title = "APE w.r.t. " + relation_title(options.relation) +
             alignment_suffix(options.alignment, options.align_origin);
  return ev;
}

Evaluation evaluate_rpe(const io::PoseSeries& ref, const io::PoseSeries& est,
                        const RpeOptions& options) {
  if (!(options.delta > 0.0) || !std::isfinite(options.delta)) {
    throw Error("RPE delta must be a positive number, got " + number_text(options.delta));
  }
  Evaluation ev = prepare(ref, est, options.association, options.alignment, options.align_origin);
  IdPairs pairs;
  std::string unit_text;
  if (options.unit == DeltaUnit::kFrames) {
    if (options.delta != std::floor(options.delta)) {
      throw Error("RPE delta in frames must be an integer, got " + number_text(options.delta));
    }
    pairs = filter_pairs_by_index(ev.est.size(), static_cast<std::size_t>(options.delta),
                                  options.all_pairs);
    unit_text = "frames";
  } else {
    // evo selects the pairs on the estimate's path.
    pairs = filter_pairs_by_path(ev.est, options.delta, options.delta * options.rel_tol,
                                 options.all_pairs);
    unit_text = "m";
  }
  if (pairs.empty()) {
    throw Error("RPE delta " + number_text(options.delta) + " " + unit_text +
                " produced no pose pairs among " + std::to_string(ev.est.size()) +
                " poses; try a smaller delta or a larger tolerance");
  }
  ev.errors = rpe_errors(ev.ref, ev.est, pairs, options.relation);
  for (const auto& pair : pairs) ev.error_pose.push_back(pair.second);
  ev.stats = compute_statistics(ev.errors);
  ev.title = "RPE w.r.t. " + relation_title(options.relation) +
             "\nfor delta = " + number_text(options.delta) + " (" + unit_text + ") using " +
             (options.all_pairs ? "all pairs" : "consecutive pairs") +
             alignment_suffix(options.alignment, options.align_origin);
  return ev;
}

}  // namespace kestrel::eval
