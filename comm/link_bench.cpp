#include "comm/link_bench.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>

#include "comm/agent_link.hpp"
#include "comm/codec.hpp"
#include "comm/local_broker.hpp"
#include "comm/station_link.hpp"
#include "comm/topics.hpp"
#include "core/error.hpp"

namespace kestrel::comm {
namespace {

using namespace std::chrono_literals;

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  p.n = v.size();
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5)];
  };
  p.p50 = at(0.5);
  p.p99 = at(0.99);
  return p;
}

// A PUBLISH on the wire: fixed header, remaining length, topic, packet id (QoS 1), property
// length, payload; QoS 1 adds a 4-byte PUBACK back.
std::size_t publish_bytes(const std::string& topic, std::size_t payload, int qos) {
  const std::size_t rest = 2 + topic.size() + (qos > 0 ? 2 : 0) + 1 + payload;
  const std::size_t len_bytes = rest < 128 ? 1 : rest < 16384 ? 2 : rest < 2097152 ? 3 : 4;
  return 1 + len_bytes + rest + (qos > 0 ? 4 : 0);
}

// utime + stime of a process, seconds (/proc/PID/stat fields 14 and 15).
double cpu_seconds(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  const std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
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

// Bytes a process read and wrote through system calls (/proc/PID/io rchar, wchar): for the
// broker, its sockets (plus its log, which stays small at the default log level).
std::pair<double, double> io_bytes(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/io");
  std::string key;
  double value = 0, r = 0, w = 0;
  while (in >> key >> value) {
    if (key == "rchar:") r = value;
    if (key == "wchar:") w = value;
  }
  return {r, w};
}

MqttOptions user(const LocalBroker& b, const std::string& name) {
  MqttOptions o;
  o.port = b.port();
  o.client_id = name;
  o.username = name;
  o.password = "pw-" + name;
  return o;
}

nlohmann::json to_json(const Percentiles& p) {
  return {{"p50", p.p50}, {"p99", p.p99}, {"n", p.n}};
}

}  // namespace

void print_link_bench(const LinkBenchResult& r) {
  std::printf("| measure (loopback, 1 agent) | p50 | p99 | n |\n|---|---|---|---|\n");
  std::printf("| pose latency agent->station (ms) | %.3f | %.3f | %zu |\n", r.pose_latency_ms.p50,
              r.pose_latency_ms.p99, r.pose_latency_ms.n);
  std::printf("| command round trip, QoS 1 + ack (ms) | %.3f | %.3f | %zu |\n",
              r.command_rtt_ms.p50, r.command_rtt_ms.p99, r.command_rtt_ms.n);
  std::printf("| ping round trip (ms) | %.3f | %.3f | %zu |\n", r.ping_rtt_ms.p50,
              r.ping_rtt_ms.p99, r.ping_rtt_ms.n);
  std::printf("\nclock offset agent-station: %.3f ms (same host: ~0)\n\n", r.clock_offset_ms);
  std::printf(
      "| agents (pose 30 Hz + status 1 Hz each) | messages sent | received | dropped | wire in "
      "kB/s | wire out kB/s | broker socket I/O kB/s | broker CPU %% | pose latency p50 / p99 "
      "ms |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const ScaleRow& s : r.scale) {
    std::printf("| %d | %llu | %llu | %llu | %.1f | %.1f | %.1f | %.1f | %.2f / %.2f |\n", s.agents,
                static_cast<unsigned long long>(s.sent),
                static_cast<unsigned long long>(s.received),
                static_cast<unsigned long long>(s.dropped()), s.wire_in_kB_s, s.wire_out_kB_s,
                s.broker_read_kB_s + s.broker_written_kB_s, s.broker_cpu_percent,
                s.pose_latency_ms.p50, s.pose_latency_ms.p99);
  }
}

std::string link_bench_json(const LinkBenchResult& r) {
  nlohmann::json j;
  j["pose_latency_ms"] = to_json(r.pose_latency_ms);
  j["command_rtt_ms"] = to_json(r.command_rtt_ms);
  j["ping_rtt_ms"] = to_json(r.ping_rtt_ms);
  j["clock_offset_ms"] = r.clock_offset_ms;
  j["scale"] = nlohmann::json::array();
  for (const ScaleRow& s : r.scale) {
    j["scale"].push_back({{"agents", s.agents},
                          {"messages_sent", s.sent},
                          {"messages_received", s.received},
                          {"messages_dropped", s.dropped()},
                          {"poses_sent", s.poses_sent},
                          {"poses_received", s.poses_received},
                          {"wire_in_kB_per_s", s.wire_in_kB_s},
                          {"wire_out_kB_per_s", s.wire_out_kB_s},
                          {"broker_read_kB_per_s", s.broker_read_kB_s},
                          {"broker_written_kB_per_s", s.broker_written_kB_s},
                          {"broker_cpu_percent", s.broker_cpu_percent},
                          {"pose_latency_ms", to_json(s.pose_latency_ms)}});
  }
  return j.dump();
}

LinkBenchResult run_link_bench(const LinkBenchOptions& options) {
  int most = 1;
  for (int n : options.agent_counts) most = std::max(most, n);
  std::vector<std::pair<std::string, std::string>> users = {{"station", "pw-station"}};
  for (int i = 0; i < most; ++i)
    users.emplace_back("a" + std::to_string(i), "pw-a" + std::to_string(i));
  LocalBroker broker(users);
  const int pid = broker.pid();
  LinkBenchResult out;

  StationLinkOptions so;
  so.mqtt = user(broker, "station");
  StationLink station(so);
  std::mutex mu;
  std::vector<double> latencies_ms;
  station.on_pose([&](const std::string&, const PoseMsg& p, std::int64_t now) {
    std::lock_guard lock(mu);
    latencies_ms.push_back(static_cast<double>(now - p.t) * 1e-6);
  });
  station.start();
  if (!station.wait_connected(5s)) throw Error("link bench: the station did not connect");

  // 1. Pose latency and command round trip, one agent.
  {
    AgentLinkOptions ao;
    ao.id = "a0";
    ao.mqtt = user(broker, "a0");
    AgentLink agent(ao, [](const CommandMsg& c) { return AckMsg{c.id, 0, AckResult::kDone, ""}; });
    agent.start();
    if (!agent.wait_connected(5s)) throw Error("link bench: agent a0 did not connect");
    agent.publish(StatusMsg{});
    station.wait_for([](const auto& m) { return m.count("a0") > 0; }, 5s);
    for (int i = 0; i < options.latency_poses; ++i) {
      PoseMsg p;
      p.t = wall_clock_ns();
      p.seq = static_cast<std::uint32_t>(i + 1);
      agent.publish(p);
      std::this_thread::sleep_for(std::chrono::microseconds(33'333));
    }
    std::this_thread::sleep_for(200ms);
    std::vector<double> rtt_ms;
    for (int i = 0; i < options.command_round_trips; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      auto id = station.send_command("a0", CommandMsg{});
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
    out.pose_latency_ms = percentiles(latencies_ms);
    out.command_rtt_ms = percentiles(rtt_ms);
    out.ping_rtt_ms.p50 = view.clock.rtt_percentile_ns(0.5) * 1e-6;
    out.ping_rtt_ms.p99 = view.clock.rtt_percentile_ns(0.99) * 1e-6;
    out.ping_rtt_ms.n = view.clock.count();
    out.clock_offset_ms = view.clock.offset_ns() * 1e-6;
    latencies_ms.clear();
  }

  // 2. Scale: n agents at once, pose 30 Hz + status 1 Hz each.
  const int ticks = std::max(1, static_cast<int>(options.scale_seconds * 30.0 + 0.5));
  for (int n : options.agent_counts) {
    std::vector<std::unique_ptr<AgentLink>> agents;
    for (int i = 0; i < n; ++i) {
      AgentLinkOptions ao;
      ao.id = "a" + std::to_string(i);
      ao.mqtt = user(broker, ao.id);
      agents.push_back(std::make_unique<AgentLink>(ao, nullptr));
      agents.back()->start();
    }
    for (auto& a : agents)
      if (!a->wait_connected(5s)) throw Error("link bench: an agent did not connect");
    std::this_thread::sleep_for(300ms);
    {
      std::lock_guard lock(mu);
      latencies_ms.clear();
    }
    const auto received0 = station.client().stats().received;
    const auto agents0 = station.agents();
    const double cpu0 = cpu_seconds(pid);
    const auto io0 = io_bytes(pid);
    const auto t0 = std::chrono::steady_clock::now();
    ScaleRow row;
    row.agents = n;
    double wire_in = 0;
    for (int k = 0; k < ticks; ++k) {
      for (int i = 0; i < n; ++i) {
        const std::string id = "a" + std::to_string(i);
        PoseMsg p;
        p.t = wall_clock_ns();
        p.p = {0.01 * k, 0.02 * i, 1.0};
        p.seq = 100000u * static_cast<std::uint32_t>(n) + static_cast<std::uint32_t>(k + 1);
        agents[static_cast<std::size_t>(i)]->publish(p);
        wire_in += publish_bytes(topic_of(id, "pose"), encode(p).size(), 0);
        ++row.sent;
        ++row.poses_sent;
        if (k % 30 == 0) {
          StatusMsg s{p.t, true, "ok", "", 30, 0.5, 1, 0, 0, 0};
          agents[static_cast<std::size_t>(i)]->publish(s);
          wire_in += publish_bytes(topic_of(id, "status"), encode(s).size(), 1);
          ++row.sent;
        }
      }
      std::this_thread::sleep_until(t0 + std::chrono::microseconds(33'333 * (k + 1)));
    }
    const double seconds = ticks / 30.0;
    std::this_thread::sleep_for(500ms);  // the last messages land
    const auto io1 = io_bytes(pid);
    // Per second of publishing (the drain after it only lets the tail land).
    row.broker_cpu_percent = 100.0 * (cpu_seconds(pid) - cpu0) / seconds;
    row.broker_read_kB_s = (io1.first - io0.first) / seconds / 1000.0;
    row.broker_written_kB_s = (io1.second - io0.second) / seconds / 1000.0;
    row.received = station.client().stats().received - received0;
    for (const auto& [id, v] : station.agents()) {
      const auto it = agents0.find(id);
      row.poses_received += v.poses - (it == agents0.end() ? 0 : it->second.poses);
    }
    row.wire_in_kB_s = wire_in / seconds / 1000.0;
    // The station gets what it received of the same messages (one subscriber).
    row.wire_out_kB_s = row.sent > 0 ? row.wire_in_kB_s * static_cast<double>(row.received) /
                                           static_cast<double>(row.sent)
                                     : 0.0;
    {
      std::lock_guard lock(mu);
      row.pose_latency_ms = percentiles(latencies_ms);
    }
    out.scale.push_back(row);
  }
  return out;
}

}  // namespace kestrel::comm
