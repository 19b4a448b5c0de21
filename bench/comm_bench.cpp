// Telemetry over a real mosquitto on loopback (comm/): pose latency agent -> station, command
// round trip, and 1/5/20/50 agents publishing pose 30 Hz + status 1 Hz to one broker (aggregate
// bandwidth, broker CPU, dropped poses). Prints a table; writes bench/results/comm.json.
#include <signal.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "comm/agent_link.hpp"
#include "comm/station_link.hpp"
#include "comm/topics.hpp"
#include "tests/comm/local_broker.hpp"

namespace {

using namespace std::chrono_literals;
using kestrel::comm::AgentLink;
using kestrel::comm::AgentLinkOptions;
using kestrel::comm::StationLink;
using kestrel::comm::StationLinkOptions;

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5)];
}

double broker_cpu_seconds(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = s.rfind(')');
  if (close == std::string::npos) return 0.0;
  std::istringstream rest(s.substr(close + 2));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  return (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

int broker_pid(const std::string& dir) {
  // The fixture execs mosquitto in place of the script, so its pid is the child's: find it by
  // the config path in /proc (only our own broker has this folder on its command line).
  for (const auto& e : std::filesystem::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream in(e.path() / "cmdline");
    std::string cmd((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (cmd.find("mosquitto") != std::string::npos && cmd.find(dir) != std::string::npos) {
      return std::stoi(name);
    }
  }
  return -1;
}

kestrel::comm::MqttOptions opts(const kestrel::test::LocalBroker& b, const std::string& user) {
  kestrel::comm::MqttOptions o;
  o.port = b.port();
  o.client_id = user;
  o.username = user;
  o.password = "pw-" + user;
  return o;
}

}  // namespace

int main() {
  std::vector<std::pair<std::string, std::string>> users = {{"station", "pw-station"}};
  for (int i = 0; i < 50; ++i)
    users.emplace_back("a" + std::to_string(i), "pw-a" + std::to_string(i));
  kestrel::test::LocalBroker broker(users);
  const int pid = broker_pid(broker.dir());
  nlohmann::json out;

  StationLinkOptions so;
  so.mqtt = opts(broker, "station");
  StationLink station(so);
  std::mutex mu;
  std::vector<double> latencies_ms;
  station.on_pose([&](const std::string&, const kestrel::comm::PoseMsg& p, std::int64_t now) {
    std::lock_guard lock(mu);
    latencies_ms.push_back(static_cast<double>(now - p.t) * 1e-6);
  });
  station.start();
  station.wait_connected(5s);

  // 1. Pose latency and command round trip, one agent.
  {
    AgentLinkOptions ao;
    ao.id = "a0";
    ao.mqtt = opts(broker, "a0");
    AgentLink agent(ao, [](const kestrel::comm::CommandMsg& c) {
      return kestrel::comm::AckMsg{c.id, 0, kestrel::comm::AckResult::kDone, ""};
    });
    agent.start();
    agent.wait_connected(5s);
    agent.publish(kestrel::comm::StatusMsg{});
    station.wait_for([](const auto& m) { return m.count("a0") > 0; }, 5s);
    for (int i = 0; i < 300; ++i) {
      kestrel::comm::PoseMsg p;
      p.t = kestrel::comm::wall_clock_ns();
      p.seq = static_cast<std::uint32_t>(i + 1);
      agent.publish(p);
      std::this_thread::sleep_for(std::chrono::microseconds(33'333));
    }
    std::this_thread::sleep_for(200ms);
    std::vector<double> rtt_ms;
    for (int i = 0; i < 200; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      auto id = station.send_command("a0", kestrel::comm::CommandMsg{});
      if (id && station.wait_ack(*id, 2s)) {
        rtt_ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
      }
    }
    for (int i = 0; i < 50; ++i) {
      station.ping("a0");
      std::this_thread::sleep_for(10ms);
    }
    std::this_thread::sleep_for(100ms);
    const auto view = *station.agent("a0");
    std::lock_guard lock(mu);
    std::printf("| measure (loopback, 1 agent) | p50 | p99 | n |\n|---|---|---|---|\n");
    std::printf("| pose latency agent->station (ms) | %.3f | %.3f | %zu |\n",
                percentile(latencies_ms, 0.5), percentile(latencies_ms, 0.99), latencies_ms.size());
    std::printf("| command round trip, QoS 1 + ack (ms) | %.3f | %.3f | %zu |\n",
                percentile(rtt_ms, 0.5), percentile(rtt_ms, 0.99), rtt_ms.size());
    std::printf("| ping round trip (ms) | %.3f | %.3f | %zu |\n",
                view.clock.rtt_percentile_ns(0.5) * 1e-6, view.clock.rtt_percentile_ns(0.99) * 1e-6,
                view.clock.count());
    std::printf("clock offset agent-station: %.3f ms (same host: ~0)\n\n",
                view.clock.offset_ns() * 1e-6);
    out["pose_latency_ms"] = {{"p50", percentile(latencies_ms, 0.5)},
                              {"p99", percentile(latencies_ms, 0.99)}};
    out["command_rtt_ms"] = {{"p50", percentile(rtt_ms, 0.5)}, {"p99", percentile(rtt_ms, 0.99)}};
    out["ping_rtt_ms_p50"] = view.clock.rtt_percentile_ns(0.5) * 1e-6;
    latencies_ms.clear();
  }

  // 2. Scale: n agents, pose 30 Hz + status 1 Hz each, for 3 s.
  std::printf(
      "| agents | poses sent | poses received | dropped | station KB/s | broker CPU %% |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (int n : {1, 5, 20, 50}) {
    std::vector<std::unique_ptr<AgentLink>> agents;
    for (int i = 0; i < n; ++i) {
      AgentLinkOptions ao;
      ao.id = "a" + std::to_string(i);
      ao.mqtt = opts(broker, ao.id);
      agents.push_back(std::make_unique<AgentLink>(ao, nullptr));
      agents.back()->start();
    }
    for (auto& a : agents) a->wait_connected(5s);
    std::this_thread::sleep_for(300ms);
    const auto before = station.client().stats().received;
    const auto agents_before = station.agents();
    const double cpu0 = broker_cpu_seconds(pid);
    const auto t0 = std::chrono::steady_clock::now();
    std::uint64_t sent = 0;
    std::size_t bytes_sent = 0;
    for (int k = 0; k < 90; ++k) {
      for (int i = 0; i < n; ++i) {
        kestrel::comm::PoseMsg p;
        p.t = kestrel::comm::wall_clock_ns();
        p.p = {0.01 * k, 0.02 * i, 1.0};
        p.seq = 100000u * static_cast<std::uint32_t>(n) + static_cast<std::uint32_t>(k + 1);
        agents[i]->publish(p);
        bytes_sent += kestrel::comm::encode(p).size();
        ++sent;
        if (k % 30 == 0) {
          kestrel::comm::StatusMsg s{p.t, true, "ok", "", 30, 0.5, 1, 0, 0, 0};
          agents[i]->publish(s);
          bytes_sent += kestrel::comm::encode(s).size();
        }
      }
      std::this_thread::sleep_until(t0 + std::chrono::microseconds(33'333 * (k + 1)));
    }
    std::this_thread::sleep_for(500ms);
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = broker_cpu_seconds(pid) - cpu0;
    std::uint64_t received = 0;
    for (const auto& [id, v] : station.agents()) {
      const auto it = agents_before.find(id);
      received += v.poses - (it == agents_before.end() ? 0 : it->second.poses);
    }
    const auto msgs = station.client().stats().received - before;
    std::printf("| %d | %llu | %llu | %llu | %.1f | %.1f |\n", n,
                static_cast<unsigned long long>(sent), static_cast<unsigned long long>(received),
                static_cast<unsigned long long>(sent - std::min(sent, received)),
                bytes_sent / 3.0 / 1000.0, 100.0 * cpu / wall);
    out["scale"].push_back({{"agents", n},
                            {"poses_sent", sent},
                            {"poses_received", received},
                            {"messages_received", msgs},
                            {"payload_kB_per_s", bytes_sent / 3.0 / 1000.0},
                            {"broker_cpu_percent", 100.0 * cpu / wall}});
  }
  std::filesystem::create_directories(KESTREL_SOURCE_DIR "/bench/results");
  std::ofstream(KESTREL_SOURCE_DIR "/bench/results/comm.json") << out.dump(2) << "\n";
  return 0;
}
