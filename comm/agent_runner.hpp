#pragma once
// One agent: replays a measurement source at sensor rate through pipeline::System, publishes
// its telemetry (pose at the camera rate up to 30 Hz, status 1 Hz, occupancy-grid deltas from its
// own keyframes, the semantic object database as deltas on change plus a retained snapshot now and
// then) and executes the station's commands: pause / resume, goal and return-home (A* on the
// agent's grid -> published path), save map (trajectory + grid). Teleop is refused: a replayed
// recording cannot be steered. With video on, each camera frame also goes to the agent's
// WebRTC viewers (comm/webrtc_link.hpp) the moment it is fed, stamped with that wall-clock time.
#include <optional>
#include <string>

#include "comm/agent_link.hpp"
#include "comm/pose_stream.hpp"
#include "comm/webrtc_sender.hpp"
#include "detect/yolo_fastest.hpp"
#include "io/measurement_source.hpp"

namespace kestrel::comm {

struct AgentRunOptions {
  AgentLinkOptions link;
  double duration_s = 0.0;       // 0: the whole source
  double start_s = 0.0;          // skip this much of the source first (a later start on its path)
  bool realtime = true;          // sleep to the stamps' pace; false: as fast as it goes
  double rate = 1.0;             // real time: the stamps' pace times this (0.5: half speed)
  double grid_period_s = 2.0;    // a grid delta at most this often
  int grid_keyframe_every = 10;  // every n-th grid message is a full keyframe (late joiners)
  double robot_radius = 0.25;    // metres, for planning
  bool progress = true;
  std::optional<VideoOptions> video;  // nullopt: no video
  // Boxes for the dynamic filter and the object database, as `kestrel run --detector`:
  // yolo (real weights from models_dir, "" = found), oracle (the Kestrel sequence's
  // boxes.csv in dataset_dir: the simulator's truth, which knows its furniture) or none.
  std::string detector = "none";
  detect::YoloModel yolo_model = detect::kPipelineYoloModel;
  std::string dataset_dir;
  std::string models_dir;
  double objects_snapshot_s = 5.0;  // retained full object snapshot at most this often
  // Real time: a camera frame that arrives while this many are still with the tracker is not
  // fed (a live camera does not wait for the tracker; counted as drops in the status) but gets
  // a predicted pose (comm/pose_stream.hpp), so poses keep the camera rate. 0: every frame is
  // fed and a slow tracker slows the replay down (back-pressure). Not real time: never drops.
  int max_frames_in_flight = 2;
  double pose_wait_s =
      0.1;  // real time: a frame's tracked pose is awaited this long, then predicted
  // After the source ends the agent stays online this long (0: it leaves at once): status
  // "finished", commands still answered on its final map (a goal, save map), pings answered
  // and the last camera frame streamed on to its viewers, so that an operator can still plan
  // on, and look at, what a finished replay saw.
  double linger_s = 0.0;
};

struct AgentRunSummary {
  std::size_t frames = 0;
  std::size_t frames_dropped = 0;  // not fed: the tracker was busy (real time)
  std::size_t tracked = 0;
  std::uint64_t poses_published = 0;
  PoseStreamCounts poses;
  double camera_rate_hz = 0.0;  // camera frames read per second of wall time (the replay's pace)
  std::uint64_t grid_messages = 0;
  std::uint64_t grid_bytes = 0;
  std::uint64_t paths_published = 0;
  std::uint64_t object_messages = 0;  // deltas
  std::uint64_t object_snapshots = 0;
  std::size_t objects = 0;  // in the published table at the end
  AgentLinkCounts link;
  MqttStats mqtt;
  WebRtcStats video;  // empty without video
  bool video_on = false;
  double wall_seconds = 0.0;
};

// Throws kestrel::Error for a bad agent id, an unknown detector or unreadable inputs. Waits up to
// 10 s for the broker at start; runs anyway (and reconnects) if it is not there yet.
AgentRunSummary run_agent(io::MeasurementSource& source, const AgentRunOptions& options);

}  // namespace kestrel::comm
