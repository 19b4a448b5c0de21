#pragma once
// The telemetry schema (DESIGN.md "Telemetry"): every message an agent, the station or mapd
// exchanges. One versioned envelope {"v": kSchemaVersion, "k": kind, ...} with short keys,
// encoded as CBOR on the wire (measured smaller than JSON: bench/comm_bench.cpp); the decoder
// also accepts the same document as JSON text so that a browser may send plain JSON commands.
// Units are SI, stamps int64 ns (Timestamp), poses T_w_body.
#include <array>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "core/timestamp.hpp"

namespace kestrel::comm {

constexpr int kSchemaVersion = 1;

// The topic name of mapd's team layer (kestrel/v1/team/...): no agent may take it.
constexpr const char* kTeamName = "team";
constexpr std::size_t kMaxAgentsPerObject = 64;

struct PoseMsg {
  Timestamp t = 0;
  std::array<double, 3> p{};            // metres, world frame
  std::array<double, 4> q{0, 0, 0, 1};  // x y z w
  std::uint8_t state = 0;               // tracking::TrackingState as an integer
  std::uint32_t seq = 0;                // per-agent counter: the station checks order and gaps
};
// PoseMsg::state of a pose predicted to its frame's stamp from tracked poses (comm/pose_stream):
// the tracker skipped that frame or had not reported it yet.
constexpr std::uint8_t kPosePredicted = 4;

struct StatusMsg {
  Timestamp t = 0;
  bool online = true;  // false: the last will, or a clean shutdown
  std::string state;   // initializing, ok, lost, relocalized, paused, finished, offline
  std::string role;    // "uav" | "ugv"
  double fps = 0.0;
  double cpu = 0.0;     // share of one core used by the process, 0..n
  double health = 1.0;  // battery-like 0..1
  std::uint64_t frames = 0;
  std::uint64_t lost = 0;
  std::uint64_t drops = 0;  // queue drops (detection newest-wins, telemetry outbox)
};

struct DetectionsMsg {
  Timestamp t = 0;
  std::vector<std::pair<std::string, std::uint32_t>> counts;  // label -> boxes in this frame
  std::uint32_t dynamic_features = 0;
};

struct ObjectInfo {
  std::uint32_t id = 0;
  std::string label;
  std::array<double, 3> center{};
  std::array<double, 3> size{};
  double yaw = 0.0;
  std::uint32_t observations = 0;
  // Team map only (kestrel/v1/team/objects): the agents whose objects merged into this one.
  // Empty in an agent's own messages, and then left off the wire.
  std::vector<std::string> agents;
};

// On change only: the objects that changed since the last message and ids that disappeared.
// `full` marks a snapshot (a late subscriber or a merge resets its copy). Agents send them in
// their own world frame; mapd publishes the merged team map, always as a full snapshot, in the
// team frame under the reserved name kTeamName.
//
// `seq` orders them: it grows with every objects message of one sender, snapshots included, and
// starts from the sender's start time in microseconds so that a restarted sender goes on above
// its last run. A QoS 1 message may arrive twice and late (a client re-sends what the broker
// did not acknowledge before a crash, after what it sent since), and a late delta applied after
// a newer snapshot would bring back what that snapshot removed; receivers apply a message only
// when objects_message_is_new says so. 0 (a sender that does not number) is always applied.
struct ObjectsMsg {
  Timestamp t = 0;
  bool full = false;
  std::vector<ObjectInfo> objects;
  std::vector<std::uint32_t> removed;
  std::uint64_t seq = 0;
};

// Largest seq on the wire: the browser page compares it as a JavaScript number.
inline constexpr std::uint64_t kMaxObjectsSeq = (1ULL << 53) - 1;

// Whether an objects message numbered `seq` is newer than the last one applied from its sender
// (`last_applied`, 0 before any); see ObjectsMsg.
constexpr bool objects_message_is_new(std::uint64_t last_applied, std::uint64_t seq) {
  return seq == 0 || seq > last_applied;
}

// The first seq of a sender started at wall-clock time `start_ns`.
constexpr std::uint64_t first_objects_seq(std::int64_t start_ns) {
  return start_ns <= 0 ? 1 : static_cast<std::uint64_t>(start_ns / 1000) % kMaxObjectsSeq + 1;
}

// An occupancy-grid change against version base_seq (see comm/grid_delta.hpp). base_seq 0 with
// every cell is a keyframe of the grid.
struct GridDeltaMsg {
  Timestamp t = 0;
  std::uint32_t seq = 0;
  std::uint32_t base_seq = 0;
  std::uint32_t width = 0, height = 0;
  double resolution = 0.05;             // metres per cell
  std::array<double, 2> origin{};       // world x, y of cell (0, 0)
  std::vector<std::uint8_t> runs_zlib;  // zlib(run-length of changed cells)
};

struct PathMsg {
  Timestamp t = 0;
  std::string goal_id;                        // the command that asked for it
  std::vector<std::array<double, 2>> points;  // world x, y
  bool reached = false;
};

enum class CommandKind : std::uint8_t { kGoal, kTeleop, kPause, kResume, kReturnHome, kSaveMap };
const char* to_string(CommandKind k);

struct CommandMsg {
  std::string id;  // unique per command: duplicates are acknowledged, not executed again
  Timestamp t = 0;
  CommandKind kind = CommandKind::kPause;
  std::array<double, 3> goal{};  // x, y, yaw (kGoal)
  double v = 0.0, w = 0.0;       // m/s, rad/s (kTeleop)
  std::string path;              // kSaveMap: where to write
};

enum class AckResult : std::uint8_t { kAccepted, kDone, kRejected, kDuplicate };
const char* to_string(AckResult r);

struct AckMsg {
  std::string id;
  Timestamp t = 0;
  AckResult result = AckResult::kAccepted;
  std::string detail;
};

// Clock offset / round trip (NTP's four stamps): the station sends t0; the agent answers with
// t0, its receive stamp t1 and its send stamp t2; the station notes t3 on arrival.
struct PingMsg {
  std::uint32_t id = 0;
  Timestamp t0 = 0;
};
struct PongMsg {
  std::uint32_t id = 0;
  Timestamp t0 = 0, t1 = 0, t2 = 0;
};

using Message = std::variant<PoseMsg, StatusMsg, DetectionsMsg, ObjectsMsg, GridDeltaMsg, PathMsg,
                             CommandMsg, AckMsg, PingMsg, PongMsg>;

// The stream name of a message: the last topic level kestrel/v1/<agent>/<stream>.
const char* stream_of(const Message& m);

}  // namespace kestrel::comm
