// run_sequence as a live run (paced, threads free): a camera faster than the tracker has its
// surplus frames dropped, counted and never fed, while the IMU still all goes in; with the
// drop off, every frame is fed and the source waits. The source here replays a pre-rendered
// second of office-static at 20x its rate, so the tracker cannot keep up on any machine.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <variant>
#include <vector>

#include "pipeline/live_feed.hpp"
#include "pipeline/run_job.hpp"
#include "sim/live_source.hpp"
#include "sim/scenario.hpp"
#include "tests/pipeline/replay_source.hpp"

namespace kestrel::pipeline {
namespace {

using test::ReplaySource;

ReplaySource& office_second() {
  static ReplaySource* source = [] {
    sim::ScenarioOverrides over;
    over.duration = 1.0;
    sim::LiveSource live(sim::load_scenario("office-static", over));
    return new ReplaySource(live);
  }();
  source->rewind();
  return *source;
}

RunOptions live_options(int max_in_flight) {
  RunOptions opt;
  opt.detector = "none";
  opt.sequential = false;
  opt.paced = true;
  opt.pace_rate = 20.0;
  opt.progress = false;
  opt.strip_frames = 0;
  opt.loop_closing = false;
  opt.max_frames_in_flight = max_in_flight;
  return opt;
}

TEST(LiveRun, AFrameIsDroppedOnlyWithMaxInFlightUnanswered) {
  EXPECT_FALSE(drop_live_frame(1, 0, 2));
  EXPECT_TRUE(drop_live_frame(2, 0, 2));
  EXPECT_FALSE(drop_live_frame(2, 1, 2));
  EXPECT_TRUE(drop_live_frame(1, 0, 1));
  EXPECT_FALSE(drop_live_frame(100, 0, 0));  // 0: never
}

TEST(LiveRun, ACameraFasterThanTheTrackerHasItsSurplusFramesDropped) {
  ReplaySource& source = office_second();
  const RunSummary s = run_sequence(source, live_options(1));
  ASSERT_EQ(s.frames, source.frame_count());
  EXPECT_GT(s.dropped, 0u);
  EXPECT_LT(s.dropped, s.frames);
  // Only fed frames have poses, and the gaps the drops leave are bridged: the track holds.
  EXPECT_LE(s.trajectory.size(), s.frames - s.dropped);
  EXPECT_GE(s.tracked, (s.frames - s.dropped) / 2);
  EXPECT_EQ(s.counters.at("frames.dropped"), s.dropped);
  const nlohmann::json timing = nlohmann::json::parse(s.timing_json);
  EXPECT_EQ(timing["counters"]["frames.dropped"].get<std::size_t>(), s.dropped);
  EXPECT_EQ(nlohmann::json::parse(summary_json(s))["dropped"].get<std::size_t>(), s.dropped);
  // Frames that restarted the local map are tracked, and the summary says how many.
  EXPECT_EQ(s.bridged, s.counters.at("tracking.bridged"));
  EXPECT_EQ(nlohmann::json::parse(summary_json(s))["bridged"].get<std::size_t>(), s.bridged);
}

TEST(LiveRun, WithoutDroppingEveryFrameIsFedAndTheSourceWaits) {
  ReplaySource& source = office_second();
  const RunSummary s = run_sequence(source, live_options(0));
  EXPECT_EQ(s.frames, source.frame_count());
  EXPECT_EQ(s.dropped, 0u);
  EXPECT_EQ(s.counters.at("frames.dropped"), 0u);
  // Every frame is fed; poses for all but a lost frame the IMU could not carry.
  EXPECT_LE(s.trajectory.size(), s.frames);
  EXPECT_GE(s.tracked, s.frames / 2);
}

}  // namespace
}  // namespace kestrel::pipeline
