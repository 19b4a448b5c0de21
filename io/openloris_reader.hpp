#pragma once
// OpenLORIS-Scene sequences (RealSense D435i part), as the dataset's own tools read them:
//   color.txt + color/*.png               "stamp color/<stamp>.png", 8-bit colour
//   aligned_depth.txt + aligned_depth/    16-bit depth registered to colour, 1000 = 1 m
//   d400_accelerometer.txt                "#Time Ax Ay Az" (s, m/s^2)
//   d400_gyroscope.txt                    "#Time Gx Gy Gz" (s, rad/s)
//   groundtruth.txt                       TUM format (pose of base_link)
//   sensors.yaml                          OpenCV FileStorage: d400_color_optical_frame
//                                         {width, height, intrinsics [fx fy cx cy],
//                                         distortion_model, distortion_coefficients},
//                                         d400_gyroscope / d400_accelerometer {fps,
//                                         noise_variances, bias_variances}
//   trans_matrix.yaml                     trans_matrix: [{parent_frame, child_frame, matrix}]
//                                         with matrix = T_parent_child
// The accelerometer and gyroscope run at different rates: IMU samples are made at the gyro
// stamps inside the accelerometer's time range, the acceleration interpolated linearly.
// Colour and aligned depth are paired by nearest stamp (within max_difference, TUM style).
#include <memory>
#include <string>
#include <vector>

#include "io/dataset_lists.hpp"
#include "io/rgbd_list_source.hpp"

namespace kestrel::io {

struct OpenLorisOptions {
  std::string config_file;       // calibration override (any core/config.hpp dialect)
  double max_difference = 0.02;  // seconds, colour <-> depth
};

std::unique_ptr<RgbdListSource> open_openloris(const std::string& dir,
                                               const OpenLorisOptions& options = {});

// Gyro stamps inside the accelerometer's span, acceleration interpolated at each.
std::vector<ImuSample> merge_accel_gyro(const std::vector<StampedVector>& accel,
                                        const std::vector<StampedVector>& gyro);

}  // namespace kestrel::io
