#pragma once
// TUM RGB-D benchmark folders: rgb.txt, depth.txt (or an association file), rgb/ and depth/
// PNGs (depth 16-bit, 5000 = 1 m), groundtruth.txt.
//
// accelerometer.txt (the Kinect's tilt accelerometer: acceleration only, no gyroscope) is NOT
// streamed as IMU samples: an ImuSample with a zero gyro would tell pre-integration that the
// camera does not rotate. Calibration::has_imu stays false; read_tum_accelerometer() gives the
// raw readings to whoever wants the gravity direction.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "io/dataset_lists.hpp"
#include "io/rgbd_list_source.hpp"

namespace kestrel::io {

struct TumRgbdOptions {
  // An association file ("t_rgb rgb/x.png t_depth depth/y.png"); relative to the dataset folder
  // unless absolute. Empty: DIR/associations.txt or DIR/association.txt if present, else
  // rgb.txt and depth.txt are associated here.
  std::string association_file;
  // Calibration (any core/config.hpp dialect). Empty: DIR/calib.yaml if present, else the
  // Kinect of the freiburg1/2/3 named in the folder name.
  std::string config_file;
  // Largest |t_rgb - t_depth| for a pair, seconds (associate.py's default).
  double max_difference = 0.02;
};

std::unique_ptr<RgbdListSource> open_tum_rgbd(const std::string& dir,
                                              const TumRgbdOptions& options = {});

// The published intrinsics of the TUM Kinects (fr1, fr2 with their distortion; fr3 images are
// already undistorted), chosen from a folder name containing "freiburg1" / "fr1" etc.
// nullopt when the name says none of them.
std::optional<Calibration> tum_calibration_for(const std::string& folder_name);

// accelerometer.txt: "timestamp ax ay az" [s, m/s^2].
std::vector<StampedVector> read_tum_accelerometer(const std::string& path);

}  // namespace kestrel::io
