// Bytes per second per agent for the seed's telemetry mix, MQTT framing included: pose 30 Hz,
// status + detections summary 1 Hz, objects on change (a 25-object scene where 3 objects change
// each second). The encoding with fewer bytes is the one comm/ uses; the goal is <= 12 KB/s.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "comm/codec.hpp"
#include "comm/topics.hpp"

namespace kestrel::comm {
namespace {

// An MQTT v5 PUBLISH on the wire: fixed header, remaining length, topic, packet id (QoS 1),
// property length, payload; QoS 1 adds a 4-byte PUBACK back.
std::size_t mqtt_bytes(const std::string& topic, std::size_t payload, int qos) {
  std::size_t rest = 2 + topic.size() + (qos > 0 ? 2 : 0) + 1 + payload;
  std::size_t len_bytes = rest < 128 ? 1 : rest < 16384 ? 2 : 3;
  return 1 + len_bytes + rest + (qos > 0 ? 4 : 0);
}

struct Budget {
  double pose = 0, status = 0, objects = 0;
  double total() const { return pose + status + objects; }
};

Budget measure(Encoding e) {
  const std::string agent = "ugv07";
  Budget b;
  // One second of a moving agent: 30 distinct poses.
  for (int i = 0; i < 30; ++i) {
    PoseMsg p;
    p.t = 1'700'000'000'000'000'000 + i * 33'333'333LL;
    p.p = {12.3456 + 0.01 * i, -3.2109 + 0.02 * i, 1.5012};
    const double yaw = 0.3 + 0.01 * i;
    p.q = {0.0123, -0.0311, std::sin(yaw / 2), std::cos(yaw / 2)};
    p.state = 1;
    p.seq = 1000 + i;
    b.pose += mqtt_bytes(topic_of(agent, "pose"), encode(p, e).size(), 0);
  }
  StatusMsg s{1'700'000'000'500'000'000, true, "ok", "ugv", 29.97, 0.83, 0.97, 12345, 3, 1};
  b.status += mqtt_bytes(topic_of(agent, "status"), encode(s, e).size(), 1);
  DetectionsMsg d{1'700'000'000'500'000'000, {{"person", 3}, {"dynamic", 3}}, 57};
  b.status += mqtt_bytes(topic_of(agent, "detections"), encode(d, e).size(), 0);
  ObjectsMsg o;
  o.t = 1'700'000'000'500'000'000;
  const char* labels[] = {"chair", "dining table", "potted plant"};
  for (std::uint32_t k = 0; k < 3; ++k) {
    o.objects.push_back(
        {100 + k, labels[k], {4.123 + k, -2.456, 0.45}, {0.52, 0.61, 0.93}, 0.785, 40 + k, {}});
  }
  b.objects += mqtt_bytes(topic_of(agent, "objects"), encode(o, e).size(), 1);
  return b;
}

TEST(TelemetryBudget, PerAgentBytesPerSecond) {
  const Budget cbor = measure(Encoding::kCbor);
  const Budget json = measure(Encoding::kJson);
  std::printf("| encoding | pose 30 Hz | status+detections 1 Hz | objects (3/s) | total B/s |\n");
  std::printf("|---|---|---|---|---|\n");
  std::printf("| CBOR | %.0f | %.0f | %.0f | %.0f |\n", cbor.pose, cbor.status, cbor.objects,
              cbor.total());
  std::printf("| JSON | %.0f | %.0f | %.0f | %.0f |\n", json.pose, json.status, json.objects,
              json.total());
  EXPECT_LT(cbor.total(), json.total());  // why the wire uses CBOR
  EXPECT_LE(cbor.total(), 12'000.0);
  // A full 25-object snapshot (sent on reconnect) still fits a second's budget.
  ObjectsMsg snap;
  snap.full = true;
  for (std::uint32_t k = 0; k < 25; ++k) {
    snap.objects.push_back({k, "potted plant", {1.0 * k, 2.0, 0.4}, {0.5, 0.5, 0.9}, 0.1, 9, {}});
  }
  const std::size_t snap_bytes = encode(snap).size();
  std::printf("25-object snapshot: %zu bytes CBOR, %zu bytes JSON\n", snap_bytes,
              encode(snap, Encoding::kJson).size());
  EXPECT_LT(snap_bytes, 4000u);
}

}  // namespace
}  // namespace kestrel::comm
