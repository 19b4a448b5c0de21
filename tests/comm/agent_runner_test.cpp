// A whole agent (comm/agent_runner.hpp) on a short rendered scene, driven by a station through
// a real broker: poses flow, pause stops them, resume restarts them, goal / home plan on the
// agent's own grid, save_map writes files, teleop is refused; a lingering agent stays online
// after its source ends.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

#include "comm/agent_runner.hpp"
#include "comm/station_link.hpp"
#include "io/dataset.hpp"
#include "sim/scenario.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"
#include "tests/comm/local_broker.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::comm {
namespace {

using namespace std::chrono_literals;

// Every test here: a broker that knows the station and ugv1, the station's link to it and the
// agent's options for it.
StationLinkOptions station_options(const test::LocalBroker& broker) {
  StationLinkOptions so;
  so.mqtt.port = broker.port();
  so.mqtt.username = "station";
  so.mqtt.password = "st";
  return so;
}

AgentRunOptions ugv1_options(const test::LocalBroker& broker) {
  AgentRunOptions ao;
  ao.link.id = "ugv1";
  ao.link.mqtt.port = broker.port();
  ao.link.mqtt.password = "pw";
  ao.progress = false;
  return ao;
}

// office-static, `seconds` long, recorded into DIR/seq of a fresh test::temp_dir(name); DIR.
std::filesystem::path record_office(const std::string& name, double seconds) {
  const std::filesystem::path dir = test::temp_dir(name);
  sim::ScenarioOverrides over;
  over.duration = seconds;
  sim::Simulator sim(sim::load_scenario("office-static", over));
  sim::record_sequence(sim, (dir / "seq").string());
  return dir;
}

TEST(AgentRunner, ObeysStationCommandsWhileReplaying) {
  namespace fs = std::filesystem;
  const fs::path dir = record_office("agent-commands", 4.0);

  test::LocalBroker broker({{"station", "st"}, {"ugv1", "pw"}});
  StationLink station(station_options(broker));
  station.start();
  ASSERT_TRUE(station.wait_connected(5s));

  AgentRunOptions ao = ugv1_options(broker);
  ao.grid_period_s = 0.5;
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

// --linger: a finished replay stays on the station's table, answering commands on its final
// map, until its time is up; then it leaves (offline by its last will's retained status).
TEST(AgentRunner, LingersOnlineAfterTheSourceEnds) {
  namespace fs = std::filesystem;
  const fs::path dir = record_office("agent-linger", 2.0);

  test::LocalBroker broker({{"station", "st"}, {"ugv1", "pw"}});
  StationLink station(station_options(broker));
  station.start();
  ASSERT_TRUE(station.wait_connected(5s));

  AgentRunOptions ao = ugv1_options(broker);
  ao.linger_s = 4.0;
  AgentRunSummary summary;
  std::thread agent([&] {
    auto source = io::open_dataset("kestrel:" + (dir / "seq").string());
    summary = run_agent(*source, ao);
  });
  ASSERT_TRUE(station.wait_for(
      [](const auto& m) { return m.count("ugv1") && m.at("ugv1").status.state == "finished"; },
      60s));
  CommandMsg save;
  save.kind = CommandKind::kSaveMap;
  save.path = (dir / "saved").string();
  const auto id = station.send_command("ugv1", save);
  ASSERT_TRUE(id);
  const auto ack = station.wait_ack(*id, 3s);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->result, AckResult::kDone) << ack->detail;
  EXPECT_TRUE(fs::exists(dir / "saved" / "trajectory.txt"));
  EXPECT_EQ(station.agent("ugv1")->status.state, "finished");  // not gone yet

  agent.join();
  EXPECT_GE(summary.wall_seconds, 2.0 + ao.linger_s - 0.5);
  EXPECT_EQ(summary.link.commands_executed, 1u);
  EXPECT_TRUE(
      station.wait_for([](const auto& m) { return m.at("ugv1").status.state == "offline"; }, 5s));
  fs::remove_all(dir);
}

// --rate: half the sensor rate takes twice the source's time (a lower bound: the replay sleeps
// to the scaled stamps, whatever the machine does besides), and every frame still arrives.
TEST(AgentRunner, HalfRateReplayTakesTwiceTheSourcesTime) {
  namespace fs = std::filesystem;
  const fs::path dir = record_office("agent-rate", 1.0);
  test::LocalBroker broker({{"station", "st"}, {"ugv1", "pw"}});
  AgentRunOptions ao = ugv1_options(broker);
  ao.rate = 0.5;
  auto source = io::open_dataset("kestrel:" + (dir / "seq").string());
  const AgentRunSummary summary = run_agent(*source, ao);
  ASSERT_GE(summary.frames, 30u);  // 1 s at 30 fps, both ends
  const double span_s = static_cast<double>(summary.frames - 1) / 30.0;
  EXPECT_GE(summary.wall_seconds, 2.0 * span_s - 0.05);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace kestrel::comm

namespace kestrel::comm {
namespace {

using namespace std::chrono_literals;

// Issue 7's pose telemetry at 30 Hz: an agent replaying a 30 fps recording in real time through
// a real mosquitto gives the station one pose per camera frame, in stamp order, whatever its
// tracker manages on this machine (frames it could not take in time get predicted poses,
// flagged). The delivered rate is measured by the station's clock.
TEST(AgentRunner, PosesReachTheStationAtTheCameraRate) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("kestrel-agent-rate-test-" + std::to_string(getpid()));
  fs::remove_all(dir);
  sim::ScenarioOverrides over;
  over.duration = 6.0;
  sim::Scenario scenario = sim::load_scenario("office-static", over);
  // A 320x240 camera: what is measured is the pose stream, and on a 2-core machine shared with
  // builds decoding 640x480 PNGs alone can keep the replay from real time.
  PinholeCamera& cam = scenario.calib.camera;
  cam.width /= 2;
  cam.height /= 2;
  cam.fx /= 2;
  cam.fy /= 2;
  cam.cx = (cam.cx + 0.5) / 2 - 0.5;
  cam.cy = (cam.cy + 0.5) / 2 - 0.5;
  sim::Simulator sim(scenario);
  sim::record_sequence(sim, (dir / "seq").string());

  test::LocalBroker broker({{"station", "st"}, {"ugv1", "pw"}});
  StationLink station(station_options(broker));
  std::mutex mu;
  std::vector<std::pair<PoseMsg, std::int64_t>> got;  // pose, arrival (station wall clock)
  station.on_pose([&](const std::string&, const PoseMsg& p, std::int64_t now) {
    std::lock_guard lock(mu);
    got.emplace_back(p, now);
  });
  station.start();
  ASSERT_TRUE(station.wait_connected(5s));

  const AgentRunOptions ao = ugv1_options(broker);
  auto source = io::open_dataset("kestrel:" + (dir / "seq").string());
  const AgentRunSummary summary = run_agent(*source, ao);
  std::this_thread::sleep_for(300ms);

  std::lock_guard lock(mu);
  ASSERT_GT(got.size(), 30u);
  int out_of_order = 0, predicted = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    predicted += got[i].first.state == kPosePredicted;
    if (i > 0 && got[i].first.t <= got[i - 1].first.t) ++out_of_order;
  }
  // The rate over the stream's middle (the first second holds the tracker's start-up).
  std::vector<std::int64_t> arrivals;
  for (const auto& [p, now] : got) arrivals.push_back(now);
  const std::size_t a = arrivals.size() / 6, b = arrivals.size() - 1 - arrivals.size() / 6;
  const double rate =
      static_cast<double>(b - a) / (1e-9 * static_cast<double>(arrivals[b] - arrivals[a]));
  const double stamp_span = to_seconds(got.back().first.t - got.front().first.t);
  std::printf(
      "poses at the station: %zu over %.2f s of sensor time, %.1f Hz delivered (station "
      "clock, middle two thirds); %d predicted (%llu interpolated, %llu extrapolated), %zu of "
      "%zu frames not fed, %llu frames with no pose; %d out of order\n",
      got.size(), stamp_span, rate, predicted,
      static_cast<unsigned long long>(summary.poses.interpolated),
      static_cast<unsigned long long>(summary.poses.extrapolated), summary.frames_dropped,
      summary.frames, static_cast<unsigned long long>(summary.poses.unsaid), out_of_order);
  std::printf("camera frames read at %.1f Hz by the replay (%s)\n", summary.camera_rate_hz,
              summary.camera_rate_hz >= 28.0 ? "real time kept" : "behind real time: CPU starved");
  EXPECT_EQ(out_of_order, 0);
  // Poses keep the pace the camera frames come at, whatever the tracker manages...
  EXPECT_GE(rate, 0.9 * summary.camera_rate_hz);
  EXPECT_LE(rate, 33.0);
  // ... which is 30 Hz when the replay keeps real time (a 2-core machine shared with builds
  // may starve the replay loop itself; the figure above says which it was).
  if (summary.camera_rate_hz >= 28.0) {
    EXPECT_GE(rate, 27.0);
  }
  // One pose per frame from the first tracked one on (before it there is nothing to say; the
  // recording starts at 0 and has 30 frames a second).
  const double after_first =
      static_cast<double>(summary.frames) - std::round(to_seconds(got.front().first.t) * 30.0);
  EXPECT_GE(static_cast<double>(got.size()), 0.95 * after_first);
  EXPECT_EQ(static_cast<std::uint64_t>(predicted),
            summary.poses.interpolated + summary.poses.extrapolated);
  EXPECT_GT(summary.poses.tracked, 0u);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace kestrel::comm
