// Telemetry area: bytes per second per agent on the wire for one agent's stream of a scene,
// encoded by comm/'s codec at the schema's rates: pose at the camera rate (30 Hz), status and
// detections 1 Hz, objects on change (each second, the objects seen that second, since each
// sighting updates the object). MQTT v5 framing is counted, as the broker carries it. Then the
// link over a real mosquitto on loopback (comm/link_bench): pose latency agent -> station p50 /
// p99, command round trip, and 1 / 5 / 20 / 50 agents on one broker (aggregate bandwidth,
// broker CPU, dropped messages); without mosquitto that part says so and the rest stands.
#include <algorithm>
#include <cstdio>

#include "apps/bench_areas.hpp"
#include "comm/codec.hpp"
#include "comm/link_bench.hpp"
#include "comm/topics.hpp"
#include "sim/scenario.hpp"
#include "sim/simulator.hpp"
#include "sim/world.hpp"

namespace kestrel::bench {
namespace {

// A PUBLISH on the wire: fixed header, remaining length, topic, packet id (QoS 1), property
// length, payload; QoS 1 adds a 4-byte PUBACK back.
std::size_t mqtt_bytes(const std::string& topic, std::size_t payload, int qos) {
  const std::size_t rest = 2 + topic.size() + (qos > 0 ? 2 : 0) + 1 + payload;
  const std::size_t len_bytes = rest < 128 ? 1 : rest < 16384 ? 2 : rest < 2097152 ? 3 : 4;
  return 1 + len_bytes + rest + (qos > 0 ? 4 : 0);
}

}  // namespace

nlohmann::json bench_telemetry(const AreaOptions& o) {
  sim::ScenarioOverrides ov;
  ov.duration = o.tiny ? 2.0 : 10.0;
  sim::Simulator sim(sim::load_scenario("cafe", ov));
  const std::string agent = "ugv07";
  const double fps = 30.0;
  const int seconds = static_cast<int>(sim.duration());
  double pose = 0, status = 0, objects = 0;
  std::uint32_t seq = 0;
  for (int sec = 0; sec < seconds; ++sec) {
    for (int i = 0; i < static_cast<int>(fps); ++i) {
      const double t = sec + i / fps;
      const SE3 T = sim.camera_pose(t);
      comm::PoseMsg p;
      p.t = from_seconds(t);
      const Vec3 x = T.translation();
      const Quat& q = T.quaternion();
      p.p = {x.x(), x.y(), x.z()};
      p.q = {q.x(), q.y(), q.z(), q.w()};
      p.state = 1;
      p.seq = seq++;
      pose += mqtt_bytes(comm::topic_of(agent, "pose"), comm::encode(p).size(), 0);
    }
    const sim::SimFrame f = sim.render(static_cast<int>(sec * fps));
    comm::StatusMsg s{
        from_seconds(sec), true, "ok", "ugv", fps, 0.8, 1.0, static_cast<std::uint64_t>(seq), 0, 0};
    status += mqtt_bytes(comm::topic_of(agent, "status"), comm::encode(s).size(), 1);
    comm::DetectionsMsg d;
    d.t = from_seconds(sec);
    comm::ObjectsMsg om;
    om.t = d.t;
    std::uint32_t people = 0;
    for (const sim::SimBox& b : f.boxes) {
      if (b.label == "person") ++people;
      if (b.instance < sim::kFirstObjectId) continue;
      const sim::StaticObject& w =
          sim.world().objects()[static_cast<std::size_t>(b.instance - sim::kFirstObjectId)];
      om.objects.push_back({static_cast<std::uint32_t>(w.id),
                            w.label,
                            {w.center.x(), w.center.y(), w.center.z()},
                            {w.size.x(), w.size.y(), w.size.z()},
                            w.yaw,
                            static_cast<std::uint32_t>(sec + 1),
                            {}});
    }
    d.counts = {{"person", people}};
    status += mqtt_bytes(comm::topic_of(agent, "detections"), comm::encode(d).size(), 0);
    if (!om.objects.empty())
      objects += mqtt_bytes(comm::topic_of(agent, "objects"), comm::encode(om).size(), 1);
  }
  const double n = std::max(1, seconds);
  std::printf("\n## Telemetry (one agent, cafe, CBOR over MQTT v5, bytes per second)\n\n");
  std::printf(
      "| pose 30 Hz | status+detections 1 Hz | objects on change | total B/s |\n"
      "|---|---|---|---|\n| %.0f | %.0f | %.0f | %.0f |\n",
      pose / n, status / n, objects / n, (pose + status + objects) / n);
  nlohmann::json link;
  try {
    comm::LinkBenchOptions lo;
    if (o.tiny) {
      lo.latency_poses = 30;
      lo.command_round_trips = 20;
      lo.agent_counts = {1, 5};
      lo.scale_seconds = 1.0;
    } else if (o.quick) {
      lo.scale_seconds = 2.0;
    }
    std::printf("\n## Telemetry link (real mosquitto on loopback)\n\n");
    const comm::LinkBenchResult r = comm::run_link_bench(lo);
    comm::print_link_bench(r);
    link = nlohmann::json::parse(comm::link_bench_json(r));
    link["status"] = "ok";
  } catch (const std::exception& e) {
    std::printf("\n| telemetry link | not measured: %s |\n|---|---|\n", e.what());
    link = {{"status", "skipped"}, {"reason", e.what()}};
  }
  return {{"scenario", "cafe"},
          {"seconds", seconds},
          {"pose_bytes_per_s", pose / n},
          {"status_bytes_per_s", status / n},
          {"objects_bytes_per_s", objects / n},
          {"total_bytes_per_s_per_agent", (pose + status + objects) / n},
          {"link", link}};
}

}  // namespace kestrel::bench
