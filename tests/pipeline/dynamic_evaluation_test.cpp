// The dynamic filter over a rendered sequence, scored against its mover masks
// (pipeline/dynamic_evaluation): the figures are those of the System's inputs, and the modes
// order as they must on ground truth.
#include "pipeline/dynamic_evaluation.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "core/error.hpp"
#include "detect/oracle_detector.hpp"
#include "io/kestrel_sequence.hpp"
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
  const DynamicEvalScene scene = load_dynamic_eval_scene(dir, {&oracle}, 12);
  ASSERT_EQ(scene.frames.size(), 12u);
  EXPECT_FALSE(scene.frames[1].depth.empty());
  EXPECT_TRUE(scene.frames[1].R_cur_prev.has_value());  // the gyro between the two frames

  const auto run = [&](dynamic::FilterMode mode, int detector, int long_gap = 0) {
    DynamicEvalOptions opt;
    opt.filter.mode = mode;
    opt.detector = detector;
    opt.long_gap = long_gap;
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
  EXPECT_EQ(hybrid.counts.dynamic_total, off.counts.dynamic_total);  // the same features
  EXPECT_EQ(hybrid.filter_ms.size(), scene.frames.size() - 1);  // the first frame is not judged
  // Truth boxes remove most movers (not all: the first frame is not judged, and the chairs
  // that are pushed later are movers of a class outside the dynamic list, standing still);
  // hybrid keeps more of the static scene than boxes alone.
  EXPECT_GE(det.counts.removed_percent(), 55.0);
  EXPECT_GE(hybrid.counts.removed_percent(), 50.0);
  EXPECT_GT(hybrid.counts.kept_percent(), det.counts.kept_percent());
  // Multi-frame evidence only adds removals.
  EXPECT_GE(multi.counts.dynamic_removed, hybrid.counts.dynamic_removed);
  EXPECT_LE(multi.counts.static_kept, hybrid.counts.static_kept);

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
