#pragma once
#include <optional>

#include "core/camera.hpp"
#include "core/imu.hpp"
#include "core/se3.hpp"
#include "core/stereo_rig.hpp"

namespace kestrel {

// The sensor setup of one agent: what a dataset's calibration files or a settings file say.
struct Calibration {
  PinholeCamera camera;                // colour / left camera
  std::optional<PinholeCamera> right;  // stereo only
  SE3 T_left_right;                    // stereo only: right camera into left camera
  SE3 T_body_camera;                   // camera into body (IMU) frame; ORB-SLAM3's Tbc
  bool has_imu = false;
  ImuNoise imu;
  double depth_scale = 5000.0;  // raw depth units per metre (TUM: 5000)
  // The depth sensor's range in metres (farther reads as a hole) where the calibration says it
  // (a kestrel sim sequence's calib.yaml does): the maps trust readings that far. Unset: the
  // maps' defaults (a D455-like sensor to 8 m).
  std::optional<double> depth_max;
  double fps = 30.0;

  bool is_stereo() const { return right.has_value(); }
  StereoRig stereo_rig() const { return StereoRig{camera, right.value_or(camera), T_left_right}; }
};

}  // namespace kestrel
