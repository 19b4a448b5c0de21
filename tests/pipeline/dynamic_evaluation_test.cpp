// The dynamic filter over a rendered sequence, scored against its mover masks
// (pipeline/dynamic_evaluation): the figures are those of the System's inputs, and the modes
// order as they must on ground truth.
#include "pipeline/dynamic_evaluation.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "core/error.hpp"
#include "detect/oracle_detector.hpp"
#include "io/dataset.hpp"
#include "io/kestrel_sequence.hpp"
#include "io/trajectory_io.hpp"
#include "sim/scenario.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::pipeline {
namespace {

TEST(DynamicEvaluation, ModesOnARenderedCafe) {
  const std::string dir = (test::temp_dir("dynamic_evaluation") / "cafe").string();
  sim::ScenarioOverrides over;
  over.duration = 1.0;
  sim::Simulator sim(sim::load_scenario("cafe", over));
  sim::record_sequence(sim, dir);
  detect::OracleDetector oracle(io::read_boxes(dir + "/boxes.csv"));
  // The same boxes, each dropped on half the frames.
  detect::OracleOptions flaky_options;
  flaky_options.false_negative_rate = 0.5;
  detect::OracleDetector flaky(io::read_boxes(dir + "/boxes.csv"), flaky_options);
  const DynamicEvalScene scene = load_dynamic_eval_scene(dir, {&oracle, &flaky}, 12);
  ASSERT_EQ(scene.frames.size(), 12u);
  EXPECT_FALSE(scene.frames[1].depth.empty());
  EXPECT_TRUE(scene.frames[1].R_cur_prev.has_value());  // the gyro between the two frames
  // Each frame's motion prior is the camera's motion since the frame before, as the System
  // hands it over: the gyro's rotation and, once the IMU predictor has its velocity window,
  // the predicted translation. Both checked against the true relative pose.
  {
    const io::PoseSeries gt = io::read_pose_series(dir + "/groundtruth.txt");
    const SE3 T_b_c = io::open_dataset("kestrel:" + dir)->calibration().T_body_camera;
    ASSERT_GE(gt.size(), scene.frames.size());
    int with_translation = 0;
    for (std::size_t k = 1; k < scene.frames.size(); ++k) {
      const DynamicEvalFrame& f = scene.frames[k];
      ASSERT_NEAR(gt.stamps[k] * 1e9, static_cast<double>(f.t), 1e3);
      const SE3 T_cur_prev = (SE3(gt.poses[k]) * T_b_c).inverse() * (SE3(gt.poses[k - 1]) * T_b_c);
      ASSERT_TRUE(f.R_cur_prev.has_value()) << k;
      const double angle = SO3(*f.R_cur_prev * T_cur_prev.so3().matrix().transpose()).log().norm();
      EXPECT_LT(angle, 2e-3) << "frame " << k;
      if (!f.t_cur_prev) continue;
      ++with_translation;
      EXPECT_LT((*f.t_cur_prev - T_cur_prev.translation()).norm(), 5e-3) << "frame " << k;
      EXPECT_GT(f.prior_translation_sigma_m, 0.0);
      EXPECT_GT(f.prior_rotation_sigma_rad, 0.0);
    }
    EXPECT_GE(with_translation, 4);  // from 0.2 s of fixes on
  }

  // The modes judge every feature the movers give: with the movers' silhouettes (on in the
  // System) the walkers' features are mostly not extracted at all.
  const auto run = [&](dynamic::FilterMode mode, int detector, int long_gap = 0,
                       int carried_frames = detect::BoxCoastOptions{}.max_frames,
                       int mover_budget_margin_px = kMoverBudgetMarginPx,
                       bool silhouettes = false) {
    DynamicEvalOptions opt;
    opt.mover_silhouettes = silhouettes;
    opt.filter.mode = mode;
    opt.detector = detector;
    opt.long_gap = long_gap;
    opt.box_coasting.max_frames = carried_frames;
    opt.mover_budget_margin_px = mover_budget_margin_px;
    return evaluate_dynamic_filter(scene, opt);
  };
  const DynamicEvalResult off = run(dynamic::FilterMode::kOff, -1);
  ASSERT_GT(off.counts.dynamic_total, 100u);
  EXPECT_EQ(off.counts.dynamic_removed, 0u);
  EXPECT_EQ(off.counts.static_kept, off.counts.static_total);
  EXPECT_TRUE(off.filter_ms.empty());

  const DynamicEvalResult det = run(dynamic::FilterMode::kDetectionOnly, 0);
  const DynamicEvalResult hybrid = run(dynamic::FilterMode::kHybrid, 0);
  const DynamicEvalResult multi = run(dynamic::FilterMode::kHybrid, 0, 5);
  // With one feature budget, the loader's features; with the movers' boxes of the frame before
  // set apart, more of the scenery's.
  const DynamicEvalResult hybrid_one =
      run(dynamic::FilterMode::kHybrid, 0, 0, detect::BoxCoastOptions{}.max_frames, -1);
  EXPECT_EQ(hybrid_one.counts.dynamic_total, off.counts.dynamic_total);
  EXPECT_EQ(hybrid_one.counts.static_total, off.counts.static_total);
  EXPECT_GT(hybrid.counts.static_total, off.counts.static_total + 500);
  EXPECT_EQ(hybrid.filter_ms.size(), scene.frames.size() - 1);  // the first frame is not judged
  // With the movers' silhouettes of the frame before, most of their features are never
  // extracted: what the silhouettes leave out is movers', not scenery.
  const DynamicEvalResult hybrid_silhouettes =
      run(dynamic::FilterMode::kHybrid, 0, 0, detect::BoxCoastOptions{}.max_frames,
          kMoverBudgetMarginPx, true);
  std::printf("on movers %zu -> %zu (kept %zu -> %zu), static %zu -> %zu\n",
              hybrid.counts.dynamic_total, hybrid_silhouettes.counts.dynamic_total,
              hybrid.counts.dynamic_total - hybrid.counts.dynamic_removed,
              hybrid_silhouettes.counts.dynamic_total - hybrid_silhouettes.counts.dynamic_removed,
              hybrid.counts.static_total, hybrid_silhouettes.counts.static_total);
  EXPECT_LT(hybrid_silhouettes.counts.dynamic_total, hybrid.counts.dynamic_total / 2);
  EXPECT_GE(hybrid_silhouettes.counts.static_total, hybrid.counts.static_total * 99 / 100);
  EXPECT_LE(hybrid_silhouettes.counts.dynamic_total - hybrid_silhouettes.counts.dynamic_removed,
            hybrid.counts.dynamic_total - hybrid.counts.dynamic_removed);
  // The silhouettes alone (the System's defaults, no budget apart) re-extract the frames too.
  const DynamicEvalResult silhouettes_alone =
      run(dynamic::FilterMode::kHybrid, 0, 0, detect::BoxCoastOptions{}.max_frames, -1, true);
  EXPECT_LT(silhouettes_alone.counts.dynamic_total, hybrid_one.counts.dynamic_total / 2);
  EXPECT_GE(silhouettes_alone.counts.static_total, hybrid_one.counts.static_total * 99 / 100);
  // Truth boxes remove most movers (not all: the first frame is not judged, and the chairs
  // that are pushed later are movers of a class outside the dynamic list, standing still);
  // hybrid keeps more of the static scene than boxes alone.
  EXPECT_GE(det.counts.removed_percent(), 55.0);
  EXPECT_GE(hybrid.counts.removed_percent(), 50.0);
  EXPECT_GT(hybrid.counts.kept_percent(), det.counts.kept_percent());
  // Multi-frame evidence only adds removals.
  EXPECT_GE(multi.counts.dynamic_removed, hybrid.counts.dynamic_removed);
  EXPECT_LE(multi.counts.static_kept, hybrid.counts.static_kept);

  // A detector that misses boxes: the movers' boxes carried over its misses remove more of
  // them than its boxes alone do.
  // On the same features (one budget: carried boxes would also move the movers' budget).
  const DynamicEvalResult flaky_carried =
      run(dynamic::FilterMode::kHybrid, 1, 0, detect::BoxCoastOptions{}.max_frames, -1);
  const DynamicEvalResult flaky_alone = run(dynamic::FilterMode::kHybrid, 1, 0, 0, -1);
  EXPECT_GT(flaky_carried.counts.dynamic_removed, flaky_alone.counts.dynamic_removed);

  DynamicEvalOptions bad;
  bad.detector = 3;
  EXPECT_THROW(evaluate_dynamic_filter(scene, bad), Error);
}

TEST(DynamicEvaluation, NotASequenceNamesTheFolder) {
  const std::string dir = test::temp_dir("dynamic_evaluation_empty").string();
  try {
    load_dynamic_eval_scene(dir, {});
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace kestrel::pipeline
