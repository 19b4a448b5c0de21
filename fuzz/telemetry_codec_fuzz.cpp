// Arbitrary bytes into the telemetry decoder, which reads what any client of the broker may
// publish: it must reject or accept, never crash or throw, and whatever it accepts must encode
// and decode again to the same message (nothing invented, nothing lost).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "comm/codec.hpp"
#include "comm/schema.hpp"

namespace {

kestrel::comm::Decoder& decoder() {
  static kestrel::comm::Decoder d([](const std::string&) {});
  return d;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace kestrel::comm;
  const auto m = decoder().decode(std::span<const std::uint8_t>(data, size), "fuzz");
  if (!m) return 0;
  for (const Encoding e : {Encoding::kCbor, Encoding::kJson}) {
    const std::vector<std::uint8_t> bytes = encode(*m, e);
    const auto again = decoder().decode(bytes, "fuzz-round-trip");
    if (!again || again->index() != m->index() || encode(*again, e) != bytes) __builtin_trap();
  }
  return 0;
}

// Seeds for the replay driver: one message of every kind, in both encodings.
extern "C" void KestrelFuzzSeeds(void (*add)(const std::uint8_t*, std::size_t)) {
  using namespace kestrel::comm;
  ObjectsMsg objects;
  objects.t = 5;
  objects.objects.push_back({3, "chair", {1, 2, 0.5}, {0.5, 0.5, 1}, 0.25, 12, {}});
  objects.removed = {9};
  objects.seq = 42;
  GridDeltaMsg grid;
  grid.seq = 4;
  grid.base_seq = 3;
  grid.width = 10;
  grid.height = 20;
  grid.runs_zlib = {1, 2, 3, 250};
  const std::vector<Message> all = {
      PoseMsg{1, {1, 2, 3}, {0, 0, 0, 1}, 1, 7},
      StatusMsg{1, true, "ok", "uav", 29.9, 0.8, 0.95, 100, 2, 1},
      DetectionsMsg{2, {{"person", 3}}, 40},
      objects,
      grid,
      PathMsg{3, "c1", {{0, 0}, {1, 1.5}}, false},
      CommandMsg{"c1", 7, CommandKind::kGoal, {1.5, -2.5, 0.5}, 0, 0, ""},
      CommandMsg{"c2", 8, CommandKind::kTeleop, {}, 0.4, -0.2, ""},
      CommandMsg{"c3", 9, CommandKind::kSaveMap, {}, 0, 0, "/tmp/map"},
      AckMsg{"c1", 10, AckResult::kDone, "path of 12 cells"},
      PingMsg{5, 123},
      PongMsg{5, 123, 456, 789}};
  for (const Encoding e : {Encoding::kCbor, Encoding::kJson}) {
    for (const Message& m : all) {
      const std::vector<std::uint8_t> b = encode(m, e);
      add(b.data(), b.size());
    }
  }
}
