// Multi-session (RunOptions::load_map, `kestrel run --load-map`): a run saves its map; a later
// run of the same world that starts elsewhere, with no ground truth to place it, loads that map,
// relocalizes in it within a second and then tracks where the first run put the same frames.
#include <gtest/gtest.h>

#include <filesystem>
#include <variant>
#include <vector>

#include "pipeline/run_job.hpp"
#include "sim/live_source.hpp"
#include "sim/scenario.hpp"
#include "tests/pipeline/replay_source.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::pipeline {
namespace {

TEST(MultiSession, ALaterRunStartingElsewhereRelocalizesInTheSavedMap) {
  sim::ScenarioOverrides over;
  over.duration = 8.0;
  sim::LiveSource live(sim::load_scenario("office-static", over));
  const Calibration calib = live.calibration();
  const std::optional<Trajectory> truth = live.ground_truth();
  const std::vector<Measurement> items = test::ReplaySource::drain(live);

  RunOptions opt;
  opt.detector = "none";
  opt.progress = false;
  opt.strip_frames = 0;
  const std::filesystem::path dir = test::temp_dir("multi_session");
  opt.out_dir = (dir / "first").string();
  test::ReplaySource first_source(calib, items, truth);
  const RunSummary first = run_sequence(first_source, opt);
  ASSERT_EQ(first.lost, 0u);
  ASSERT_TRUE(std::filesystem::exists(dir / "first" / "map.bin"));

  // Halfway through, nothing to say where it is but the map.
  opt.out_dir = (dir / "second").string();
  opt.load_map = (dir / "first" / "map.bin").string();
  test::ReplaySource second_source(calib, items, std::nullopt, 4.0);
  const RunSummary second = run_sequence(second_source, opt);
  ASSERT_GT(second.frames, 100u);
  EXPECT_GE(second.tracked + 30, second.frames);  // relocalized within a second (30 frames)
  ASSERT_TRUE(second.map_relocalized_after_s.has_value());
  EXPECT_GE(*second.map_relocalized_after_s, 0.0);
  EXPECT_LE(*second.map_relocalized_after_s, 1.0);
  EXPECT_FALSE(first.map_relocalized_after_s.has_value());  // no map loaded
  // Where the first run put the same frames: the same world, to a few millimetres.
  std::size_t close = 0, compared = 0;
  for (std::size_t k = 0; k < second.trajectory.size(); ++k) {
    const auto i = nearest_pose(first.trajectory, second.trajectory.stamps[k], 1e-3);
    if (!i) continue;
    ++compared;
    const double d =
        (second.trajectory.poses[k].translation() - first.trajectory.poses[*i].translation())
            .norm();
    if (d < 0.05) ++close;
  }
  EXPECT_GE(compared, second.frames - 1);
  EXPECT_GE(close + 30, second.frames) << close << " of " << compared << " within 5 cm";
}

}  // namespace
}  // namespace kestrel::pipeline
