#include "comm/telemetry_observer.hpp"

#include <ctime>

namespace kestrel::comm {
namespace {

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

TelemetryObserver::TelemetryObserver(AgentLink& link, TelemetryOptions options)
    : link_(link),
      options_(options),
      poses_([&link](const PoseMsg& m) { link.publish(m); }, options.pose),
      cpu_seconds_at_status_(process_cpu_seconds()) {}

void TelemetryObserver::on_frame(const pipeline::FrameReport& r) {
  bool send_status = false;
  {
    std::lock_guard lock(mutex_);
    ++frames_;
    if (r.lost()) ++lost_;
    state_ = tracking::to_string(r.state);
    dynamic_features_ = static_cast<std::uint32_t>(r.dynamic_features);
    detections_ = static_cast<std::uint32_t>(r.detections);
    send_status = std::chrono::steady_clock::now() - last_status_ >=
                  std::chrono::duration<double>(1.0 / options_.status_rate_hz);
  }
  poses_.on_tracked(r.t, r.T_w_body, static_cast<std::uint8_t>(r.state), wall_clock_ns());
  if (send_status) publish_status();
}

void TelemetryObserver::publish_status(const std::string& state_override) {
  StatusMsg s;
  DetectionsMsg d;
  {
    std::lock_guard lock(mutex_);
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last_status_).count();
    const double cpu = process_cpu_seconds();
    s.t = wall_clock_ns();
    s.online = true;
    s.state = state_override.empty() ? state_ : state_override;
    s.fps = dt > 0 ? static_cast<double>(frames_ - frames_at_status_) / dt : 0.0;
    s.cpu = dt > 0 ? (cpu - cpu_seconds_at_status_) / dt : 0.0;
    // Battery-like health: the share of frames tracked (a lost agent is an unhealthy one).
    s.health = frames_ > 0 ? 1.0 - static_cast<double>(lost_) / static_cast<double>(frames_) : 1.0;
    s.frames = frames_;
    s.lost = lost_;
    s.drops = drops_;
    last_status_ = now;
    cpu_seconds_at_status_ = cpu;
    frames_at_status_ = frames_;
    d.t = s.t;
    d.counts.emplace_back("dynamic", detections_);
    d.dynamic_features = dynamic_features_;
  }
  link_.publish(s);
  link_.publish(d);
}

void TelemetryObserver::set_drops(std::uint64_t drops) {
  std::lock_guard lock(mutex_);
  drops_ = drops;
}

std::uint64_t TelemetryObserver::poses_published() const { return poses_.counts().published; }

std::uint64_t TelemetryObserver::frames_reported() const {
  std::lock_guard lock(mutex_);
  return frames_;
}

}  // namespace kestrel::comm
