#pragma once
// The agent's pose telemetry at the camera rate (issue 7: pose 30 Hz), whatever the tracker
// manages: one pose per camera frame, in stamp order, each stamped with its own frame's sensor
// time. A frame the tracker reported goes out with the tracked pose the moment it is reported;
// a frame it skipped (dropped while it was busy) or has not reported within max_wait gets a
// pose predicted to its stamp, flagged kPosePredicted: interpolated between the tracked poses
// around it when the tracker is already past it, else extrapolated at the last tracked
// velocity (at most max_extrapolation past the last tracked pose; beyond that nothing is
// said). No threads: the tracking thread calls on_tracked, the replay loop calls
// on_camera_frame and poll; a mutex guards the state.
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>

#include "comm/schema.hpp"
#include "core/se3.hpp"
#include "core/timestamp.hpp"

namespace kestrel::comm {

struct PoseStreamOptions {
  double rate_hz = 30.0;                      // at most this many poses per second of sensor time
  std::int64_t max_wait_ns = 100'000'000;     // wall: a frame's tracked pose is awaited this long
  Timestamp max_extrapolation = 500'000'000;  // sensor time past the last tracked pose
};

struct PoseStreamCounts {
  std::uint64_t published = 0;
  std::uint64_t tracked = 0;       // of them, the tracker's own pose of the frame
  std::uint64_t interpolated = 0;  // predicted between two tracked poses
  std::uint64_t extrapolated = 0;  // predicted past the last tracked pose
  std::uint64_t unsaid = 0;        // frames with no pose to give (nothing tracked, or too old)
  std::uint64_t decimated = 0;     // frames above rate_hz
};

class PoseStream {
 public:
  using Publish = std::function<void(const PoseMsg&)>;
  explicit PoseStream(Publish publish, PoseStreamOptions options = {});

  // A camera frame of sensor stamp t reached the agent at wall time now_ns (fed or dropped).
  void on_camera_frame(Timestamp t, std::int64_t now_ns);
  // The tracker's result for the frame at t; state is tracking::TrackingState as an integer
  // (only kOk and kRelocalized poses anchor predictions). Publishes what it unblocks.
  void on_tracked(Timestamp t, const SE3& T_w_body, std::uint8_t state, std::int64_t now_ns);
  // Publishes the frames whose wait ran out.
  void poll(std::int64_t now_ns);
  // End of the source: every pending frame is given its pose now.
  void flush();

  PoseStreamCounts counts() const;

 private:
  struct Pending {
    Timestamp t;
    std::int64_t arrived_ns;
  };
  struct Tracked {
    Timestamp t;
    SE3 T;
    std::uint8_t state;
  };
  void drain(std::int64_t now_ns, bool force);               // mutex held
  bool emit(Timestamp t, const SE3& T, std::uint8_t state);  // false: decimated

  Publish publish_;
  PoseStreamOptions options_;
  mutable std::mutex mutex_;
  std::deque<Pending> pending_;
  std::deque<Tracked> tracked_;  // recent reports, in stamp order
  std::deque<Tracked> anchors_;  // recent good poses (ok, relocalized), in stamp order
  Timestamp last_published_t_ = -1;
  std::uint32_t seq_ = 0;
  PoseStreamCounts counts_;
};

}  // namespace kestrel::comm
