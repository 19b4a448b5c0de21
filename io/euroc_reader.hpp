#pragma once
// EuRoC MAV and TUM-VI in the ASL layout:
//   [DIR/]mav0/cam0/data.csv + data/*.png, cam1/ (optional: stereo), imu0/data.csv,
//   */sensor.yaml, state_groundtruth_estimate0/data.csv (EuRoC) or mocap0/data.csv (TUM-VI).
// Stereo pairs are the cam0 and cam1 rows with equal stamps; rows without a partner are
// counted (unmatched_left/right) and left out. The distortion model comes from the yaml
// (radial-tangential for EuRoC, equidistant for TUM-VI). Calibration is read from
//   options.config_file, else DIR/dso/camchain.yaml (Kalibr; TUM-VI ships it) when the
//   per-camera sensor.yaml holds no intrinsics, else the per-sensor sensor.yaml files.
// "body" is the IMU frame: T_body_camera = T_BS(imu)^-1 * T_BS(cam0).
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "io/dataset_lists.hpp"
#include "io/indexed_source.hpp"

namespace kestrel::io {

struct EurocOptions {
  std::string config_file;     // a Kalibr camchain or any core/config.hpp dialect
  bool stereo = true;          // false: cam0 only, as monocular RgbdFrames without depth
  std::string name = "euroc";  // "euroc" or "tumvi", for describe()
};

class EurocReader : public IndexedSource {
 public:
  EurocReader(const std::string& dir, const EurocOptions& options = {});

  const Calibration& calibration() const override { return calib_; }
  std::optional<Trajectory> ground_truth() const override { return ground_truth_; }
  std::string describe() const override { return description_; }

  std::size_t unmatched_left() const { return unmatched_left_; }
  std::size_t unmatched_right() const { return unmatched_right_; }

 protected:
  Measurement load_frame(std::size_t index) const override;

 private:
  struct Pair {
    Timestamp t = 0;
    std::string left, right;  // image paths; right empty for monocular
    int left_line = 0, right_line = 0;
  };
  std::string left_csv_, right_csv_;
  std::vector<Pair> frames_;
  Calibration calib_;
  std::optional<Trajectory> ground_truth_;
  std::string description_;
  std::size_t unmatched_left_ = 0, unmatched_right_ = 0;
};

std::unique_ptr<EurocReader> open_euroc(const std::string& dir, const EurocOptions& options = {});

// Kalibr camchain (cam0, optional cam1: intrinsics, distortion, resolution, T_cam_imu).
// Sets camera, right, T_left_right and T_body_camera; the IMU part is left as given.
void load_kalibr_camchain(const std::string& path, Calibration* calib);

}  // namespace kestrel::io
