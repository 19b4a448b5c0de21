// Evaluation area: eval/ recomputes evo's stored KITTI 00 figures and the TUM benchmark's
// DynaSLAM ATE from the shared files, in this run; the table quotes the relative difference.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <tuple>

#include "apps/bench_areas.hpp"
#include "eval/trajectory_evaluation.hpp"
#include "io/trajectory_io.hpp"

namespace kestrel::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

double rel(double ours, double ref) { return std::abs(ours - ref) / std::abs(ref); }

// ate.txt holds "RMSE: 0.0163" where the run reported it.
std::optional<double> reported_rmse(const fs::path& ate_txt) {
  std::ifstream in(ate_txt);
  std::string key;
  double value = 0.0;
  while (in >> key) {
    if (key == "RMSE:" && in >> value) return value;
  }
  return std::nullopt;
}

}  // namespace

json bench_evaluation(const AreaOptions& o) {
  json j;
  const fs::path evo = fs::path(o.shared_data) / "evo";
  std::printf("\n## Evaluation (eval/ against evo's stored results and the TUM tool)\n\n");
  std::printf("| case | figure | ours | reference | relative error |\n|---|---|---|---|---|\n");
  if (!fs::exists(evo / "KITTI_00_gt.txt")) {
    std::printf("| KITTI 00 | - | - | - | %s missing |\n", evo.c_str());
  } else {
    const io::PoseSeries gt = io::read_pose_series((evo / "KITTI_00_gt.txt").string());
    for (const auto& [name, file, prefix] :
         {std::tuple{"orb", "KITTI_00_ORB.txt", "orb"}, {"sptam", "KITTI_00_SPTAM.txt", "sptam"}}) {
      const io::PoseSeries est = io::read_pose_series((evo / file).string());
      eval::ApeOptions ape;
      ape.alignment = eval::Alignment::kSe3;
      eval::RpeOptions rpe;
      rpe.delta = 10.0;
      rpe.unit = eval::DeltaUnit::kMeters;
      const double ape_rmse = eval::evaluate_ape(gt, est, ape).stats.rmse;
      const double rpe_rmse = eval::evaluate_rpe(gt, est, rpe).stats.rmse;
      for (const auto& [what, ours, stored] :
           {std::tuple{"ape_se3_rmse", ape_rmse, std::string(prefix) + "_ape.stats.json"},
            {"rpe_10m_rmse", rpe_rmse, std::string(prefix) + "_rpe.stats.json"}}) {
        std::ifstream in(evo / "results" / stored);
        const double ref = json::parse(in).at("rmse").get<double>();
        std::printf("| KITTI_00 %s | %s | %.12f | %.12f | %.1e |\n", name, what, ours, ref,
                    rel(ours, ref));
        j["kitti_00"][name][what] = {{"ours", ours}, {"evo", ref}, {"rel_error", rel(ours, ref)}};
      }
    }
  }
  const fs::path tum = fs::path(o.shared_data) / "tum_fr3";
  for (const char* seq : {"fr3_walk_xyz", "fr3_walk_static", "fr3_walk_rpy", "fr3_walk_halfsphere",
                          "fr3_sitting_static"}) {
    const fs::path est_file = tum / "dynaslam" / seq / "CameraTrajectory_0.txt";
    const fs::path gt_file = tum / "groundtruth" / (std::string(seq) + ".txt");
    if (!fs::exists(est_file) || !fs::exists(gt_file)) {
      std::printf("| DynaSLAM %s | ate_rmse | - | - | files missing |\n", seq);
      continue;
    }
    eval::ApeOptions ape;
    ape.association = {eval::AssociationMethod::kTum, eval::kTumMaxDiff, 0.0};
    ape.alignment = eval::Alignment::kSe3;
    const eval::Evaluation ev = eval::evaluate_ape(io::read_pose_series(gt_file.string()),
                                                   io::read_pose_series(est_file.string()), ape);
    json row = {{"ours", ev.stats.rmse}, {"pairs", ev.stats.count}};
    // ate.txt rounds to 4 decimals, so the relative error is bounded by that rounding.
    if (const auto ref = reported_rmse(tum / "dynaslam" / seq / "ate.txt")) {
      row["ate_txt"] = *ref;
      row["abs_error"] = std::abs(ev.stats.rmse - *ref);
      row["rel_error"] = rel(ev.stats.rmse, *ref);
      std::printf("| DynaSLAM %s | ate_rmse (%zu pairs) | %.6f | %.4f | %.1e |\n", seq,
                  ev.stats.count, ev.stats.rmse, *ref, rel(ev.stats.rmse, *ref));
    } else {
      std::printf("| DynaSLAM %s | ate_rmse (%zu pairs) | %.6f | no RMSE in ate.txt | - |\n", seq,
                  ev.stats.count, ev.stats.rmse);
    }
    j["dynaslam_tum_ate"][seq] = row;
  }
  return j;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace kestrel::bench
