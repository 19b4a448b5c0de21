#pragma once
// Telemetry over a real mosquitto on loopback (comm/local_broker.hpp), measured through the
// agent and station links themselves: pose latency agent -> station and command round trip
// with one agent, then n agents at once publishing pose 30 Hz + status 1 Hz to one broker
// (aggregate bandwidth, broker CPU, messages dropped, pose latency under that load). What
// `kestrel bench --only telemetry` and build/bench/bench_comm print. Needs mosquitto
// (scripts/setup); throws kestrel::Error without it.
#include <cstdint>
#include <string>
#include <vector>

namespace kestrel::comm {

struct LinkBenchOptions {
  int latency_poses = 300;  // one agent, at 30 Hz
  int command_round_trips = 200;
  std::vector<int> agent_counts = {1, 5, 20, 50};
  double scale_seconds = 3.0;
};

struct Percentiles {
  double p50 = 0, p99 = 0;
  std::size_t n = 0;
};

struct ScaleRow {
  int agents = 0;
  std::uint64_t sent = 0;      // messages the agents published (pose + status)
  std::uint64_t received = 0;  // of them, what reached the station
  std::uint64_t dropped() const { return sent > received ? sent - received : 0; }
  std::uint64_t poses_sent = 0, poses_received = 0;
  double wire_in_kB_s = 0;   // MQTT PUBLISH bytes agents -> broker (framing counted), kB/s
  double wire_out_kB_s = 0;  // broker -> station
  double broker_read_kB_s = 0, broker_written_kB_s = 0;  // the broker's own socket I/O (/proc)
  double broker_cpu_percent = 0;                         // of one core
  Percentiles pose_latency_ms;                           // every pose the station received
};

struct LinkBenchResult {
  Percentiles pose_latency_ms;  // one agent, 30 Hz
  Percentiles command_rtt_ms;   // QoS 1 command + acknowledgement
  Percentiles ping_rtt_ms;      // clock-sync pings
  double clock_offset_ms = 0;   // agent - station (same host: ~0)
  std::vector<ScaleRow> scale;
};

LinkBenchResult run_link_bench(const LinkBenchOptions& options = {});
// The two markdown tables (one agent; scale), to stdout.
void print_link_bench(const LinkBenchResult& result);
// The figures as JSON text (pose_latency_ms, command_rtt_ms, ping_rtt_ms, scale[]).
std::string link_bench_json(const LinkBenchResult& result);

}  // namespace kestrel::comm
