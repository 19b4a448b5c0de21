#pragma once
// The pipeline's telemetry sink (pipeline::Observer, DSO's output-wrapper seam): hands frame
// reports to the pose stream (comm/pose_stream.hpp: one pose per camera frame up to
// pose.rate_hz by sensor time, predicted for frames the tracker skipped), a status at
// status_rate_hz (by wall time) and a detections summary with each status. Runs on the
// tracking thread; it only encodes and queues, the network work happens on the MQTT loop thread.
#include <chrono>
#include <mutex>
#include <string>

#include "comm/agent_link.hpp"
#include "comm/pose_stream.hpp"
#include "pipeline/system.hpp"

namespace kestrel::comm {

struct TelemetryOptions {
  PoseStreamOptions pose;  // rate_hz 30
  double status_rate_hz = 1.0;
};

class TelemetryObserver : public pipeline::Observer {
 public:
  TelemetryObserver(AgentLink& link, TelemetryOptions options = {});

  void on_frame(const pipeline::FrameReport& report) override;
  // Publishes a status now (also used while paused, when no frames arrive).
  void publish_status(const std::string& state_override = {});
  void set_drops(std::uint64_t drops);

  std::uint64_t poses_published() const;
  std::uint64_t frames_reported() const;
  // The replay loop registers every camera frame here (fed or dropped) and polls it.
  PoseStream& poses() { return poses_; }

 private:
  AgentLink& link_;
  TelemetryOptions options_;
  PoseStream poses_;
  mutable std::mutex mutex_;
  std::string state_ = "initializing";
  std::uint64_t frames_ = 0, lost_ = 0, drops_ = 0;
  std::uint64_t frames_at_status_ = 0;
  std::uint32_t dynamic_features_ = 0, detections_ = 0;
  std::chrono::steady_clock::time_point last_status_ = std::chrono::steady_clock::now();
  double cpu_seconds_at_status_ = 0.0;
};

}  // namespace kestrel::comm
