// `kestrel eval ape|rpe REF EST`: evo_ape / evo_rpe figures for TUM, EuRoC and KITTI files
// (formats detected from the content). Flags only; the work is in eval/.
#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include "apps/commands.hpp"
#include "eval/plot_writer.hpp"
#include "eval/result_json.hpp"
#include "eval/trajectory_evaluation.hpp"
#include "io/trajectory_io.hpp"

namespace {

using namespace kestrel;

struct EvalArgs {
  std::string ref;
  std::string est;
  std::string ref_times;
  std::string est_times;
  std::string json;
  std::string plot;
  std::string align = "none";
  bool align_origin = false;
  double max_diff = eval::kEvoMaxDiff;
  double offset = 0.0;
  std::string assoc = "evo";
  std::string relation = "trans";
  CLI::Option* max_diff_option = nullptr;
  // rpe only
  double delta = 1.0;
  std::string unit = "frames";
  bool all_pairs = false;
  double tol = 0.1;
};

const std::map<std::string, eval::Alignment> kAlignments = {{"none", eval::Alignment::kNone},
                                                            {"se3", eval::Alignment::kSe3},
                                                            {"sim3", eval::Alignment::kSim3}};
const std::map<std::string, eval::PoseRelation> kRelations = {
    {"trans", eval::PoseRelation::kTranslation},
    {"angle_deg", eval::PoseRelation::kAngleDeg},
    {"angle_rad", eval::PoseRelation::kAngleRad},
    {"full", eval::PoseRelation::kFull},
    {"rot", eval::PoseRelation::kRotationPart}};

std::vector<std::string> keys(const auto& map) {
  std::vector<std::string> out;
  for (const auto& [k, v] : map) out.push_back(k);
  return out;
}

void add_common_options(CLI::App* cmd, EvalArgs& a) {
  cmd->add_option("REF", a.ref, "reference trajectory (TUM, EuRoC csv or KITTI)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("EST", a.est, "estimated trajectory (TUM, EuRoC csv or KITTI)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--align", a.align, "Umeyama alignment of the estimate: none, se3 or sim3")
      ->check(CLI::IsMember(keys(kAlignments)));
  cmd->add_flag("--align-origin", a.align_origin,
                "move the estimate so that its first pose is the reference's (without --align)");
  a.max_diff_option =
      cmd->add_option("--max-diff", a.max_diff,
                      "max. timestamp difference for association, s (default 0.01 evo, 0.02 tum)")
          ->check(CLI::PositiveNumber);
  cmd->add_option("--offset", a.offset, "time offset added to the estimate's stamps, s")
      ->check(CLI::Number);
  cmd->add_option("--assoc", a.assoc,
                  "timestamp association: evo (nearest stamp) or tum (associate.py)")
      ->check(CLI::IsMember({"evo", "tum"}));
  cmd->add_option("--pose-relation", a.relation,
                  "error on: trans, angle_deg, angle_rad, full (|E - I|_F) or rot (|R - I|_F)")
      ->check(CLI::IsMember(keys(kRelations)));
  cmd->add_option("--ref-times", a.ref_times, "stamps for a KITTI reference, one per line")
      ->check(CLI::ExistingFile);
  cmd->add_option("--est-times", a.est_times, "stamps for a KITTI estimate, one per line")
      ->check(CLI::ExistingFile);
  cmd->add_option("--json", a.json, "write the statistics as JSON");
  cmd->add_option("--plot", a.plot, "write a PNG of the trajectories and the error (gnuplot)");
}

eval::AssociationOptions association_options(const EvalArgs& a) {
  if (a.align_origin && a.align != "none") {
    throw CLI::ValidationError("--align-origin", "cannot be combined with --align " + a.align);
  }
  eval::AssociationOptions o;
  o.method = a.assoc == "tum" ? eval::AssociationMethod::kTum : eval::AssociationMethod::kEvo;
  o.max_diff =
      a.max_diff_option->count() > 0
          ? a.max_diff
          : (o.method == eval::AssociationMethod::kTum ? eval::kTumMaxDiff : eval::kEvoMaxDiff);
  o.offset = a.offset;
  return o;
}

void report(const eval::Evaluation& ev, const EvalArgs& a, const std::string& metric) {
  std::printf("%s\n\n", ev.title.c_str());
  const std::pair<const char*, double> rows[] = {
      {"max", ev.stats.max}, {"mean", ev.stats.mean}, {"median", ev.stats.median},
      {"min", ev.stats.min}, {"rmse", ev.stats.rmse}, {"sse", ev.stats.sse},
      {"std", ev.stats.std}};
  for (const auto& [name, value] : rows) std::printf("%10s\t%.6f\n", name, value);
  std::printf("%10s\t%zu\n", "pairs", ev.stats.count);
  if (!a.json.empty()) eval::write_statistics_json(a.json, ev.stats, ev.title);
  if (!a.plot.empty()) {
    const std::string unit = eval::relation_unit(kRelations.at(a.relation));
    eval::write_evaluation_plot(a.plot, ev, metric + (unit.empty() ? "" : " (" + unit + ")"));
  }
}

void run_ape(const EvalArgs& a) {
  eval::ApeOptions o;
  o.association = association_options(a);
  o.alignment = kAlignments.at(a.align);
  o.align_origin = a.align_origin;
  o.relation = kRelations.at(a.relation);
  const io::PoseSeries ref = io::read_pose_series(a.ref, a.ref_times);
  const io::PoseSeries est = io::read_pose_series(a.est, a.est_times);
  report(eval::evaluate_ape(ref, est, o), a, "APE");
}

void run_rpe(const EvalArgs& a) {
  eval::RpeOptions o;
  o.association = association_options(a);
  o.alignment = kAlignments.at(a.align);
  o.align_origin = a.align_origin;
  o.relation = kRelations.at(a.relation);
  o.delta = a.delta;
  o.unit = a.unit == "m" ? eval::DeltaUnit::kMeters : eval::DeltaUnit::kFrames;
  o.all_pairs = a.all_pairs;
  o.rel_tol = a.tol;
  if (o.unit == eval::DeltaUnit::kFrames &&
      a.delta != static_cast<double>(static_cast<long>(a.delta))) {
    throw CLI::ValidationError("--delta", "must be a whole number of frames with --unit frames");
  }
  const io::PoseSeries ref = io::read_pose_series(a.ref, a.ref_times);
  const io::PoseSeries est = io::read_pose_series(a.est, a.est_times);
  report(eval::evaluate_rpe(ref, est, o), a, "RPE");
}

void setup_eval(CLI::App& app) {
  auto* eval_cmd = app.add_subcommand(
      "eval", "Evaluate a trajectory against a reference (evo-compatible APE/RPE)");
  eval_cmd->require_subcommand(1);

  auto ape_args = std::make_shared<EvalArgs>();
  auto* ape = eval_cmd->add_subcommand("ape", "absolute pose error, as evo_ape");
  add_common_options(ape, *ape_args);
  ape->callback([ape_args] { run_ape(*ape_args); });

  auto rpe_args = std::make_shared<EvalArgs>();
  auto* rpe = eval_cmd->add_subcommand("rpe", "relative pose error, as evo_rpe");
  add_common_options(rpe, *rpe_args);
  rpe->add_option("--delta", rpe_args->delta, "distance between the poses of a pair")
      ->check(CLI::PositiveNumber);
  rpe->add_option("--unit", rpe_args->unit, "unit of --delta: frames or m (travelled path)")
      ->check(CLI::IsMember({"frames", "m"}));
  rpe->add_flag("--all-pairs", rpe_args->all_pairs, "use all pairs instead of consecutive ones");
  rpe->add_option("--tol", rpe_args->tol,
                  "all-pairs tolerance on the path delta, relative to --delta (default 0.1)")
      ->check(CLI::NonNegativeNumber);
  rpe->callback([rpe_args] { run_rpe(*rpe_args); });
}

}  // namespace

KESTREL_COMMAND(100, setup_eval);
