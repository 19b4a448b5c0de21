#pragma once
// One YAML file per run. Three dialects are read:
//  * Kestrel's own (documented in config/default.yaml): sections `camera`, `right_camera`,
//    `imu`, `T_body_camera`, `T_left_right`, `depth_scale`, `fps`;
//  * ORB-SLAM3 settings files (`Camera.fx` / `Camera1.fx`, `IMU.NoiseGyro`, `Tbc`, ...),
//    both the old and the 1.0 format, including OpenCV's `%YAML:1.0` header and matrices;
//  * a EuRoC / Kalibr `sensor.yaml` of one camera (`intrinsics`, `T_BS`, ...) or one IMU.
// Every error names the file, the line and the field.
#include <string>

#include "core/calibration.hpp"

namespace kestrel {

struct Config {
  Calibration calib;
  std::string source;  // file it was read from ("" for defaults)
};

enum class ConfigDialect { kKestrel, kOrbSlam3, kEurocCamera, kEurocImu };

// Reads any of the dialects above, detected from the keys present.
Config load_config(const std::string& path);
Config parse_config(const std::string& text, const std::string& name_for_errors);
ConfigDialect detect_dialect(const std::string& text, const std::string& name_for_errors);

// EuRoC sensor.yaml parts, used by the EuRoC / TUM-VI readers.
PinholeCamera load_euroc_camera(const std::string& path, SE3* T_body_camera);
ImuNoise load_euroc_imu(const std::string& path);

// Writes a Kestrel-dialect file that load_config reads back to the same values.
std::string to_yaml(const Calibration& calib);

}  // namespace kestrel
