#pragma once
// One agent: replays a measurement source at sensor rate through pipeline::System, publishes
// its telemetry (pose 30 Hz, status 1 Hz, occupancy-grid deltas from its own keyframes) and
// executes the station's commands: pause / resume, goal and return-home (A* on the agent's
// grid -> published path), save map (trajectory + grid). Teleop is refused: a replayed
// recording cannot be steered. With video on, each camera frame also goes to the agent's
// WebRTC viewers (comm/webrtc_link.hpp) the moment it is fed, stamped with that wall-clock time.
#include <optional>
#include <string>

#include "comm/agent_link.hpp"
#include "comm/webrtc_sender.hpp"
#include "io/measurement_source.hpp"

namespace kestrel::comm {

struct AgentRunOptions {
  AgentLinkOptions link;
  double duration_s = 0.0;       // 0: the whole source
  bool realtime = true;          // sleep to the stamps' pace; false: as fast as it goes
  double grid_period_s = 2.0;    // a grid delta at most this often
  int grid_keyframe_every = 10;  // every n-th grid message is a full keyframe (late joiners)
  double robot_radius = 0.25;    // metres, for planning
  bool progress = true;
  std::optional<VideoOptions> video;  // nullopt: no video
};

struct AgentRunSummary {
  std::size_t frames = 0;
  std::size_t tracked = 0;
  std::uint64_t poses_published = 0;
  std::uint64_t grid_messages = 0;
  std::uint64_t grid_bytes = 0;
  std::uint64_t paths_published = 0;
  AgentLinkCounts link;
  MqttStats mqtt;
  WebRtcStats video;  // empty without video
  bool video_on = false;
  double wall_seconds = 0.0;
};

// Throws kestrel::Error for a bad agent id or unreadable inputs. Waits up to 10 s for the
// broker at start; runs anyway (and reconnects) if it is not there yet.
AgentRunSummary run_agent(io::MeasurementSource& source, const AgentRunOptions& options);

}  // namespace kestrel::comm
