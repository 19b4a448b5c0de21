// A whole agent (comm/agent_runner.hpp) on a short rendered scene, driven by a station through
// a real broker: poses flow, pause stops them, resume restarts them, goal / home plan on the
// agent's own grid, save_map writes files, teleop is refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <thread>

#include "comm/agent_runner.hpp"
#include "comm/station_link.hpp"
#include "io/dataset.hpp"
#include "sim/scenario.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"
#include "tests/comm/local_broker.hpp"

namespace kestrel::comm {
namespace {

using namespace std::chrono_literals;

TEST(AgentRunner, ObeysStationCommandsWhileReplaying) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("kestrel-agent-test-" + std::to_string(getpid()));
  fs::remove_all(dir);
  sim::ScenarioOverrides over;
  over.duration = 4.0;
  sim::Simulator sim(sim::load_scenario("office-static", over));
  sim::record_sequence(sim, (dir / "seq").string());

  test::LocalBroker broker({{"station", "st"}, {"ugv1", "pw"}});
  StationLinkOptions so;
  so.mqtt.port = broker.port();
  so.mqtt.username = "station";
  so.mqtt.password = "st";
  StationLink station(so);
  station.start();
  ASSERT_TRUE(station.wait_connected(5s));

  AgentRunOptions ao;
  ao.link.id = "ugv1";
  ao.link.mqtt.port = broker.port();
  ao.link.mqtt.password = "pw";
  ao.grid_period_s = 0.5;
  ao.progress = false;
  AgentRunSummary summary;
  std::thread agent([&] {
    auto source = io::open_dataset("kestrel:" + (dir / "seq").string());
    summary = run_agent(*source, ao);
  });

  auto poses = [&] {
    auto a = station.agent("ugv1");
    return a ? a->poses : 0;
  };
  ASSERT_TRUE(station.wait_for(
      [](const auto& m) { return m.count("ugv1") && m.at("ugv1").poses > 5; }, 30s));
  auto send = [&](CommandMsg c) {
    auto id = station.send_command("ugv1", c);
    EXPECT_TRUE(id);
    auto ack = station.wait_ack(*id, 10s);
    EXPECT_TRUE(ack) << to_string(c.kind);
    return ack.value_or(AckMsg{});
  };
  CommandMsg pause;
  pause.kind = CommandKind::kPause;
  EXPECT_EQ(send(pause).result, AckResult::kDone);
  EXPECT_TRUE(
      station.wait_for([](const auto& m) { return m.at("ugv1").status.state == "paused"; }, 5s));
  std::this_thread::sleep_for(300ms);  // frames already in the queues may still finish
  const auto paused_at = poses();
  std::this_thread::sleep_for(1200ms);
  EXPECT_EQ(poses(), paused_at);  // nothing moves while paused

  CommandMsg resume;
  resume.kind = CommandKind::kResume;
  EXPECT_EQ(send(resume).result, AckResult::kDone);
  EXPECT_TRUE(station.wait_for([&](const auto& m) { return m.at("ugv1").poses > paused_at; }, 10s));

  CommandMsg home;
  home.kind = CommandKind::kReturnHome;
  const AckMsg home_ack = send(home);
  if (home_ack.result == AckResult::kDone) {
    ASSERT_TRUE(station.wait_for(
        [&](const auto& m) {
          return m.at("ugv1").path && m.at("ugv1").path->goal_id == home_ack.id;
        },
        5s));
    EXPECT_GE(station.agent("ugv1")->path->points.size(), 1u);
  } else {
    EXPECT_EQ(home_ack.result, AckResult::kRejected);
    EXPECT_FALSE(home_ack.detail.empty());  // the planner says why
  }
  std::printf("return home: %s (%s)\n", to_string(home_ack.result), home_ack.detail.c_str());

  CommandMsg save;
  save.kind = CommandKind::kSaveMap;
  save.path = (dir / "saved").string();
  EXPECT_EQ(send(save).result, AckResult::kDone);
  EXPECT_TRUE(fs::exists(dir / "saved" / "trajectory.txt"));

  CommandMsg teleop;
  teleop.kind = CommandKind::kTeleop;
  teleop.v = 0.5;
  EXPECT_EQ(send(teleop).result, AckResult::kRejected);

  agent.join();
  EXPECT_GT(summary.frames, 100u);
  EXPECT_EQ(summary.link.commands_executed, 5u);
  EXPECT_GT(summary.grid_messages, 0u);
  EXPECT_TRUE(
      station.wait_for([](const auto& m) { return m.at("ugv1").status.state == "offline"; }, 5s));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace kestrel::comm
