#pragma once
// The simulator as a live camera: frames rendered when the stream reaches them, interleaved
// with the IMU, never written to disk. A ten-minute scene is 18 000 frames (about 15 GB as a
// Kestrel sequence); this is how the endurance benchmark and `kestrel run --dataset sim:NAME`
// see one. The stream is exactly the one `kestrel sim` writes and the sequence reader reads
// back (same stamps, pixels, IMU and ground truth).
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "io/measurement_source.hpp"
#include "sim/simulator.hpp"

namespace kestrel::sim {

class LiveSource : public io::MeasurementSource {
 public:
  // recent_truth: how many of the latest frames keep their mover mask for truth_mask(): the
  // tracker asks for a frame's mask once it leaves the frame queue (8 deep), 0.6 MB each.
  explicit LiveSource(Scenario scenario, std::size_t recent_truth = 16);

  std::optional<Measurement> next() override;
  const Calibration& calibration() const override { return sim_.calibration(); }
  std::optional<Trajectory> ground_truth() const override { return truth_; }
  std::size_t frame_count() const override { return frames_.size(); }
  std::string describe() const override;

  // Mover mask of a recently streamed frame (16-bit ids), or an empty Image once it has aged
  // out of the window or for a stamp never streamed. Safe to call from another thread (the
  // tracker's) while next() runs.
  Image truth_mask(Timestamp t) const;
  const Simulator& simulator() const { return sim_; }

 private:
  struct Recent {
    Timestamp stamp = 0;
    Image mask;
  };

  Simulator sim_;
  std::vector<int> frames_;  // indices of the frames the sensor delivers (drops removed)
  std::vector<Timestamp> stamps_;
  std::vector<ImuSample> imu_;
  Trajectory truth_;
  std::size_t next_frame_ = 0;
  std::size_t next_imu_ = 0;
  std::size_t recent_capacity_;
  mutable std::mutex recent_mutex_;
  std::deque<Recent> recent_;
};

}  // namespace kestrel::sim
