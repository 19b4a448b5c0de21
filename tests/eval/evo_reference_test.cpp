// evo's stored results for the KITTI 00 sequence (ORB-SLAM2 and S-PTAM), reproduced to 1e-9.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "eval/trajectory_evaluation.hpp"
#include "io/trajectory_io.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::eval {
namespace {

constexpr double kRelTol = 1e-9;

io::PoseSeries evo_file(const std::string& name) {
  return io::read_pose_series(test::shared_data("evo/" + name).string());
}

nlohmann::json stored(const std::string& name) {
  std::ifstream in(test::shared_data("evo/results/" + name));
  EXPECT_TRUE(in) << name;
  return nlohmann::json::parse(in);
}

void expect_near_rel(double actual, double expected, const std::string& what) {
  EXPECT_NEAR(actual, expected, kRelTol * std::abs(expected)) << what;
}

void expect_stats(const ErrorStatistics& s, const nlohmann::json& j) {
  expect_near_rel(s.rmse, j.at("rmse"), "rmse");
  expect_near_rel(s.mean, j.at("mean"), "mean");
  expect_near_rel(s.median, j.at("median"), "median");
  expect_near_rel(s.std, j.at("std"), "std");
  expect_near_rel(s.min, j.at("min"), "min");
  expect_near_rel(s.max, j.at("max"), "max");
  expect_near_rel(s.sse, j.at("sse"), "sse");
}

ErrorStatistics ape_se3(const std::string& est) {
  ApeOptions options;
  options.alignment = Alignment::kSe3;
  const Evaluation ev = evaluate_ape(evo_file("KITTI_00_gt.txt"), evo_file(est), options);
  EXPECT_EQ(ev.stats.count, 4541u);
  return ev.stats;
}

ErrorStatistics rpe_10m(const std::string& est) {
  RpeOptions options;
  options.delta = 10.0;
  options.unit = DeltaUnit::kMeters;
  return evaluate_rpe(evo_file("KITTI_00_gt.txt"), evo_file(est), options).stats;
}

TEST(EvoReference, KittiOrbApeSe3) {
  const ErrorStatistics s = ape_se3("KITTI_00_ORB.txt");
  EXPECT_NEAR(s.rmse, 1.3034497145650266, 1.3034497145650266 * kRelTol);
  expect_stats(s, stored("orb_ape.stats.json"));
}

TEST(EvoReference, KittiSptamApeSe3) {
  const ErrorStatistics s = ape_se3("KITTI_00_SPTAM.txt");
  EXPECT_NEAR(s.rmse, 3.738487907582613, 3.738487907582613 * kRelTol);
  expect_stats(s, stored("sptam_ape.stats.json"));
}

TEST(EvoReference, KittiOrbRpe10mConsecutive) {
  const ErrorStatistics s = rpe_10m("KITTI_00_ORB.txt");
  EXPECT_NEAR(s.rmse, 0.22626134329310163, 0.22626134329310163 * kRelTol);
  expect_stats(s, stored("orb_rpe.stats.json"));
}

TEST(EvoReference, KittiSptamRpe10mConsecutive) {
  const ErrorStatistics s = rpe_10m("KITTI_00_SPTAM.txt");
  EXPECT_NEAR(s.rmse, 0.27607109043606004, 0.27607109043606004 * kRelTol);
  expect_stats(s, stored("sptam_rpe.stats.json"));
}

// evo_rpe-for-each --mode path: all pairs on the reference path within 10% of each bin, the
// mean RPE translation per bin.
void expect_for_each(const std::string& est_name, const std::string& stats_name) {
  const io::PoseSeries ref = evo_file("KITTI_00_gt.txt");
  const io::PoseSeries est = evo_file(est_name);
  const nlohmann::json expected = stored(stats_name);
  for (const double bin : {10.0, 20.0, 30.0, 40.0, 50.0}) {
    const IdPairs pairs = filter_pairs_by_path(ref.poses, bin, 0.1 * bin, true);
    ASSERT_FALSE(pairs.empty());
    const ErrorStatistics s =
        compute_statistics(rpe_errors(ref.poses, est.poses, pairs, PoseRelation::kTranslation));
    char key[16];
    std::snprintf(key, sizeof(key), "%.1f", bin);
    expect_near_rel(s.mean, expected.at(key), est_name + " bin " + key);
  }
}

// Disabled: the stored for-each means (1.163 m at 10 m for ORB) are ~7x evo's own consecutive
// 10 m RPE mean on the same files (0.169 m, reproduced above to 1e-9). Neither evo's current
// all-pairs path filter (argmin on accumulated distance) nor its legacy one (bounded binary
// search), nor direct-distance pairs, reproduce them (0.172 / 0.172 / 0.483 m at 10 m).
// evo's own for-each (MichaelGrupp/evo evo/main_rpe_for_each.py at 94067223 and 62fa0dfa, with
// evo/algorithms/{filters,metrics}.py of the same commits) is exactly this test: pairs from
// filter_pairs_by_path(ref, bin, bin * tol, all_pairs=True), then the standard RPE
// (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), translation norm, mean. On these files that gives 0.1716 m
// (ORB) and 0.2601 m (S-PTAM) at 10 m, and S-PTAM is worse than ORB at every length, while the
// stored figures have S-PTAM ~17% better. No per-pose product of the four poses matches either.
// The stored means instead grow like a per-estimate error of ~11% (ORB) / ~9.5% (S-PTAM) of the
// sub-sequence length (fits: est translation scale 0.888-0.893 / 0.904-0.907, or a body-frame
// yaw of 6.2-6.5 / 5.1 deg), none exact, so the zips (evo test/data/res_files/*rpe-for-each.zip,
// not readable here) were computed from other inputs than these files; kept runnable.
TEST(EvoReference, DISABLED_KittiOrbRpeForEach) {
  expect_for_each("KITTI_00_ORB.txt", "orb_rpe-for-each.stats.json");
}

TEST(EvoReference, DISABLED_KittiSptamRpeForEach) {
  expect_for_each("KITTI_00_SPTAM.txt", "sptam_rpe-for-each.stats.json");
}

// What holds without the stored figures: all-pairs sub-sequences of 10 m on the reference give
// nearly the consecutive 10 m RPE, and the mean error grows with the sub-sequence length.
TEST(EvoReference, RpeForEachIsConsistentWithConsecutiveRpe) {
  const io::PoseSeries ref = evo_file("KITTI_00_gt.txt");
  const io::PoseSeries est = evo_file("KITTI_00_ORB.txt");
  double previous = 0.0;
  for (const double bin : {10.0, 20.0, 30.0, 40.0, 50.0}) {
    const IdPairs pairs = filter_pairs_by_path(ref.poses, bin, 0.1 * bin, true);
    ASSERT_GT(pairs.size(), 4000u);
    const double mean =
        compute_statistics(rpe_errors(ref.poses, est.poses, pairs, PoseRelation::kTranslation))
            .mean;
    if (bin == 10.0) {
      EXPECT_NEAR(mean, stored("orb_rpe.stats.json").at("mean").get<double>(), 0.01);
    }
    EXPECT_GT(mean, previous);
    previous = mean;
  }
}

}  // namespace
}  // namespace kestrel::eval
