// The TUM benchmark's evaluate_ate.py figures for DynaSLAM on fr3 (associate.py, max.
// difference 0.02 s, SE(3) alignment of the estimate onto the ground truth).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include "eval/trajectory_evaluation.hpp"
#include "io/trajectory_io.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::eval {
namespace {

struct AteCase {
  const char* sequence;
  double rmse;
  std::size_t pairs;
};

class TumAte : public ::testing::TestWithParam<AteCase> {};

// ate.txt holds "RMSE: 0.0163" (4 decimals) where the run reported it; empty otherwise.
std::optional<double> reported_rmse(const std::filesystem::path& ate_txt) {
  std::ifstream in(ate_txt);
  std::string key;
  double value = 0.0;
  while (in >> key) {
    if (key == "RMSE:" && in >> value) return value;
  }
  return std::nullopt;
}

TEST_P(TumAte, MatchesEvaluateAtePy) {
  const AteCase c = GetParam();
  const std::string seq = c.sequence;
  const io::PoseSeries gt =
      io::read_pose_series(test::shared_data("tum_fr3/groundtruth/" + seq + ".txt").string());
  const io::PoseSeries est = io::read_pose_series(
      test::shared_data("tum_fr3/dynaslam/" + seq + "/CameraTrajectory_0.txt").string());
  ApeOptions options;
  options.association = {AssociationMethod::kTum, kTumMaxDiff, 0.0};
  options.alignment = Alignment::kSe3;
  const Evaluation ev = evaluate_ape(gt, est, options);
  EXPECT_EQ(ev.stats.count, c.pairs);
  EXPECT_NEAR(ev.stats.rmse, c.rmse, 1e-5);
  if (const auto reported =
          reported_rmse(test::shared_data("tum_fr3/dynaslam/" + seq + "/ate.txt"))) {
    EXPECT_NEAR(ev.stats.rmse, *reported, 0.5e-4 + 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(DynaSlamFr3, TumAte,
                         ::testing::Values(AteCase{"fr3_walk_xyz", 0.016314, 757},
                                           AteCase{"fr3_walk_static", 0.007244, 314},
                                           AteCase{"fr3_walk_rpy", 0.038196, 783},
                                           AteCase{"fr3_walk_halfsphere", 0.028747, 1018},
                                           AteCase{"fr3_sitting_static", 0.006368, 557}),
                         [](const auto& info) { return std::string(info.param.sequence); });

}  // namespace
}  // namespace kestrel::eval
