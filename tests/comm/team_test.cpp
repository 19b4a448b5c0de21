// Issue 7's team test: three `kestrel agent`s replay the crowded `market` from three starts
// along its path (8 s apart, --start-time), each with its own world frame, the oracle
// detector's boxes and the real pipeline (tracking, mapping thread, object database); mapd
// (in this process) merges what they publish through a real mosquitto; the team map as the
// station receives it on kestrel/v1/team/objects is scored against the world's objects:
// recall and precision >= 0.9 and no world object twice.
//
// Measured at 2995f50 (semantic/: a box filled by a surface that goes on past its edges, like
// market's stall before the table at (6.8, 1.5) it hides, is a part, not a view of the box's
// object; objects need a whole view to be reported), 3 x 8 s on the loaded 2-core machine:
// recall 1.00 (6/6), precision 1.00 (6 reported), 0 duplicates, one chair merged across a2
// and a3; 109 s wall of which 32 s rendering.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "comm/mapd.hpp"
#include "comm/station_link.hpp"
#include "io/dataset.hpp"
#include "io/kestrel_sequence.hpp"
#include "sim/scenario.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"
#include "tests/comm/local_broker.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::comm {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr double kAgentSeconds = 8.0;
constexpr double kStartGap = 8.0;  // the three starts cover the first lap (24 s)
constexpr int kAgents = 3;

std::string kestrel_binary() {
  const char* dir = std::getenv("KESTREL_BUILD_DIR");
  return std::string(dir ? dir : KESTREL_BINARY_DIR) + "/kestrel";
}

pid_t spawn(const std::vector<std::string>& args, const std::string& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

struct Scores {
  int truth = 0, reported = 0, matched = 0, duplicates = 0;
  double recall = 0, precision = 0;
};

// World objects the agents' cameras saw well (a box of >= 400 px, at most half hidden) in at
// least 30 of their frames: what a team could map. Greedy nearest matching as in
// tests/semantic/sim_object_run.cpp: within half the object's largest side (0.15..0.5 m), same
// label first. A world object with two team objects of its label within its largest side (at
// least 1 m) counts as a duplicate.
Scores score(const std::vector<io::SequenceObject>& world,
             const std::vector<io::SequenceBox>& boxes,
             const std::vector<std::pair<double, double>>& windows,
             const std::vector<ObjectInfo>& team) {
  std::map<int, int> seen;
  for (const auto& b : boxes) {
    const double t = to_seconds(b.t);
    bool inside = false;
    for (const auto& [t0, t1] : windows) inside = inside || (t >= t0 && t <= t1);
    if (inside && (b.x_max - b.x_min) * (b.y_max - b.y_min) >= 400 && b.occluded <= 0.5) {
      ++seen[b.instance];
    }
  }
  std::vector<const io::SequenceObject*> truth;
  for (const auto& w : world) {
    const bool in = seen[w.id] >= 30;
    std::printf("  world %-13s (%5.2f, %5.2f, %4.2f): %3d frames%s\n", w.label.c_str(),
                w.center.x(), w.center.y(), w.center.z(), seen[w.id], in ? "" : " (not counted)");
    if (in) truth.push_back(&w);
  }
  Scores s;
  s.truth = static_cast<int>(truth.size());
  s.reported = static_cast<int>(team.size());
  struct Pair {
    double d;
    std::size_t t, r;
  };
  std::vector<Pair> pairs;
  auto centre = [](const ObjectInfo& o) { return Vec3(o.center[0], o.center[1], o.center[2]); };
  for (std::size_t t = 0; t < truth.size(); ++t)
    for (std::size_t r = 0; r < team.size(); ++r) {
      const double d = (truth[t]->center - centre(team[r])).norm();
      const double gate = std::min(0.5, std::max(0.15, 0.5 * truth[t]->size.maxCoeff()));
      if (d < gate) pairs.push_back({d + (truth[t]->label == team[r].label ? 0.0 : 10.0), t, r});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d < b.d; });
  std::vector<bool> t_used(truth.size()), r_used(team.size());
  for (const Pair& p : pairs) {
    if (t_used[p.t] || r_used[p.r]) continue;
    t_used[p.t] = r_used[p.r] = true;
    ++s.matched;
  }
  for (const auto* w : truth) {
    int near = 0;
    for (const auto& o : team)
      if (o.label == w->label && (w->center - centre(o)).norm() < std::max(1.0, w->size.maxCoeff()))
        ++near;
    s.duplicates += near > 1;
  }
  for (std::size_t r = 0; r < team.size(); ++r) {
    std::string who;
    for (const auto& a : team[r].agents) who += (who.empty() ? "" : ",") + a;
    std::printf("  team  %-13s (%5.2f, %5.2f, %4.2f) by %-8s %s\n", team[r].label.c_str(),
                team[r].center[0], team[r].center[1], team[r].center[2], who.c_str(),
                r_used[r] ? "matched" : "EXTRA");
  }
  s.recall = s.truth ? double(s.matched) / s.truth : 0.0;
  s.precision = s.reported ? double(s.matched) / s.reported : 0.0;
  return s;
}

TEST(Team, ThreeAgentsInMarketShareOneMap) {
  const auto wall0 = std::chrono::steady_clock::now();
  const fs::path dir =
      fs::temp_directory_path() / ("kestrel-team-test-" + std::to_string(getpid()));
  fs::remove_all(dir);
  // One rendering shared by the three agents (each replays its own window of it).
  sim::ScenarioOverrides over;
  over.duration = (kAgents - 1) * kStartGap + kAgentSeconds + 0.2;
  sim::Simulator sim(sim::load_scenario("market", over));
  const std::string seq = (dir / "market").string();
  sim::record_sequence(sim, seq);
  const double render_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();

  std::vector<std::pair<std::string, std::string>> users = {{"station", "st"}, {"mapd", "md"}};
  for (int i = 1; i <= kAgents; ++i) users.push_back({"a" + std::to_string(i), "p"});
  test::LocalBroker broker(users);

  // The operator's start poses: the ground truth body pose at each agent's first frame,
  // gravity-aligned (x, y, z, yaw); mapd refines them from shared objects.
  const auto gt = *io::open_dataset("kestrel:" + seq)->ground_truth();
  MapdOptions mo;
  mo.mqtt.port = broker.port();
  mo.mqtt.username = "mapd";
  mo.mqtt.password = "md";
  std::vector<std::pair<double, double>> windows;
  for (int i = 0; i < kAgents; ++i) {
    const std::string id = "a" + std::to_string(i + 1);
    const double t0 = i * kStartGap;
    windows.push_back({t0, t0 + kAgentSeconds});
    const auto it = std::lower_bound(gt.stamps.begin(), gt.stamps.end(), t0 - 1e-6);
    const SE3& T = gt.poses[static_cast<std::size_t>(it - gt.stamps.begin())];
    const Mat3 R = T.rotation();
    Pose4 p;
    p.t = {T.translation().x(), T.translation().y(), T.translation().z()};
    p.yaw = std::atan2(R(1, 0), R(0, 0));
    mo.agents.push_back(id);
    mo.starts.push_back({id, p});
  }
  mo.publish_period_s = 0.5;
  Mapd mapd(mo);
  mapd.start();
  ASSERT_TRUE(mapd.wait_connected(5s));
  StationLinkOptions so;
  so.mqtt.port = broker.port();
  so.mqtt.username = "station";
  so.mqtt.password = "st";
  StationLink station(so);
  station.start();
  ASSERT_TRUE(station.wait_connected(5s));

  std::vector<pid_t> pids;
  for (int i = 0; i < kAgents; ++i) {
    const std::string id = "a" + std::to_string(i + 1);
    pids.push_back(
        spawn({kestrel_binary(), "agent", "--id", id, "--password", "p", "--broker",
               "mqtt://127.0.0.1:" + std::to_string(broker.port()), "--source", "kestrel:" + seq,
               "--start-time", std::to_string(i * kStartGap), "--duration",
               std::to_string(kAgentSeconds), "--fast", "--detector", "oracle", "--video", "off"},
              (dir / (id + ".log")).string()));
  }
  int running = kAgents;
  const auto deadline = std::chrono::steady_clock::now() + 150s * test::time_scale();
  while (running > 0 && std::chrono::steady_clock::now() < deadline) {
    mapd.spin_once();
    for (pid_t& pid : pids) {
      int status = 0;
      if (pid > 0 && waitpid(pid, &status, WNOHANG) == pid) {
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "agent exit " << status;
        pid = -1;
        --running;
      }
    }
    std::this_thread::sleep_for(50ms);
  }
  for (pid_t pid : pids)
    if (pid > 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  ASSERT_EQ(running, 0) << "agents did not finish in time";
  // The agents' last deltas and snapshots are in; publish the final team map and wait for it.
  std::this_thread::sleep_for(500ms);
  mapd.spin_once(true);
  const auto final_map = mapd.last();
  ASSERT_TRUE(station.wait_for(
      [&](const auto& m) {
        const auto it = m.find(kTeamName);
        return it != m.end() && it->second.objects.size() == final_map.objects.size();
      },
      5s));
  std::vector<ObjectInfo> team;
  const auto team_view = station.agent(kTeamName);  // a copy the loop can rely on
  for (const auto& [id, o] : team_view->objects) team.push_back(o);

  for (int i = 1; i <= kAgents; ++i) {
    std::ifstream log(dir / ("a" + std::to_string(i) + ".log"));
    std::string line;  // the agent's closing lines: its summary and its pose stream
    while (std::getline(log, line))
      if (line.rfind("agent ", 0) == 0) std::printf("%s\n", line.c_str());
  }
  for (const auto& [agent, f] : final_map.frames) {
    std::printf(
        "  frame %s: x %.3f y %.3f z %.3f yaw %.2f deg, prior x %.3f y %.3f yaw %.2f, "
        "%d matched\n",
        agent.c_str(), f.T_team_agent.t[0], f.T_team_agent.t[1], f.T_team_agent.t[2],
        f.T_team_agent.yaw * 180 / M_PI, f.prior.t[0], f.prior.t[1], f.prior.yaw * 180 / M_PI,
        f.matched);
  }
  const Scores s = score(io::read_objects(seq + "/objects.json"),
                         io::read_boxes(seq + "/boxes.csv"), windows, team);
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  std::printf(
      "team map: recall %.2f (%d/%d), precision %.2f (%d reported), %d duplicates, "
      "%d merged across agents; mapd rejected %llu; wall %.1f s (render %.1f s)\n",
      s.recall, s.matched, s.truth, s.precision, s.reported, s.duplicates, final_map.merged,
      static_cast<unsigned long long>(mapd.counts().rejected()), wall, render_s);
  EXPECT_GE(s.truth, 5);
  EXPECT_GE(s.recall, 0.9);
  EXPECT_GE(s.precision, 0.9);
  EXPECT_EQ(s.duplicates, 0);
  EXPECT_EQ(mapd.counts().rejected(), 0u);
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace kestrel::comm
