#pragma once
// The common shape of the dataset readers: a small in-memory index (frame stamps, IMU samples)
// and frames decoded only when next() reaches them, so a long dataset never sits in memory.
#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "io/measurement_source.hpp"

namespace kestrel::io {

class IndexedSource : public MeasurementSource {
 public:
  // Frames and IMU samples merged by stamp; on equal stamps the IMU sample comes first, so the
  // IMU data up to a frame is always complete when the frame arrives.
  std::optional<Measurement> next() final;
  std::size_t frame_count() const final { return frame_stamps_.size(); }

  std::size_t imu_count() const { return imu_.size(); }
  const std::vector<Timestamp>& frame_stamps() const { return frame_stamps_; }
  const std::vector<ImuSample>& imu_samples() const { return imu_; }
  // Earliest and latest stamp of any measurement; nullopt for an empty source.
  std::optional<std::pair<Timestamp, Timestamp>> time_span() const;
  // Starts the stream again from the first measurement.
  void rewind() { next_frame_ = next_imu_ = 0; }

 protected:
  // Both must be sorted by stamp (the readers check the files and report the offending line).
  void set_streams(std::vector<Timestamp> frame_stamps, std::vector<ImuSample> imu);
  // Decodes frame `index`; throws kestrel::Error naming the list file, its line and the image.
  virtual Measurement load_frame(std::size_t index) const = 0;

 private:
  std::vector<Timestamp> frame_stamps_;
  std::vector<ImuSample> imu_;
  std::size_t next_frame_ = 0;
  std::size_t next_imu_ = 0;
};

}  // namespace kestrel::io
