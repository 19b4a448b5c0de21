#pragma once
// What every dataset reader (and the simulator's live feed) offers the pipeline: one
// time-ordered stream of measurements, the calibration, and ground truth where there is one.
#include <optional>
#include <string>

#include "core/calibration.hpp"
#include "core/frame.hpp"
#include "core/trajectory.hpp"

namespace kestrel::io {

class MeasurementSource {
 public:
  virtual ~MeasurementSource() = default;
  // Next measurement in time order (frames and IMU samples interleaved); nullopt at the end.
  // Throws kestrel::Error naming the file when a file is missing or malformed.
  virtual std::optional<Measurement> next() = 0;
  virtual const Calibration& calibration() const = 0;
  // Ground truth T_w_body, when the dataset has it.
  virtual std::optional<Trajectory> ground_truth() const = 0;
  // Number of frames (not IMU samples) the stream will yield, for progress bars.
  virtual std::size_t frame_count() const = 0;
  // A short description, e.g. "tum:/data/fr3_walking_xyz (RGB-D, 859 frames)".
  virtual std::string describe() const = 0;
};

}  // namespace kestrel::io
