// Telemetry over a real mosquitto on loopback (comm/link_bench): pose latency agent -> station,
// command round trip, and 1/5/20/50 agents publishing pose 30 Hz + status 1 Hz to one broker
// (aggregate bandwidth, broker CPU, dropped messages). Prints the tables; writes
// bench/results/comm.json. `kestrel bench --only telemetry` runs the same measurement.
#include <filesystem>
#include <fstream>

#include "comm/link_bench.hpp"

int main() {
  const auto r = kestrel::comm::run_link_bench();
  kestrel::comm::print_link_bench(r);
  std::filesystem::create_directories(KESTREL_SOURCE_DIR "/bench/results");
  std::ofstream(KESTREL_SOURCE_DIR "/bench/results/comm.json")
      << kestrel::comm::link_bench_json(r) << "\n";
  return 0;
}
