#pragma once
// Pinhole camera with the two distortion models the supported datasets use:
// radial-tangential (EuRoC, TUM RGB-D, OpenCV's k1 k2 p1 p2 k3) and equidistant
// (Kannala-Brandt k1..k4, TUM-VI's fisheyes).
#include <array>
#include <optional>
#include <string>

#include "core/eigen_types.hpp"

namespace kestrel {

enum class DistortionModel { kNone, kRadTan, kEquidistant };

std::string to_string(DistortionModel m);
std::optional<DistortionModel> distortion_model_from_string(const std::string& name);

struct PinholeCamera {
  int width = 640;
  int height = 480;
  double fx = 525.0;
  double fy = 525.0;
  double cx = 319.5;
  double cy = 239.5;
  DistortionModel model = DistortionModel::kNone;
  // radtan: k1 k2 p1 p2 k3; equidistant: k1 k2 k3 k4 (fifth unused)
  std::array<double, 5> dist{0, 0, 0, 0, 0};

  // Normalized image-plane point (x/z, y/z) to distorted normalized point.
  Vec2 distort(const Vec2& xn) const;
  // Inverse of distort by Gauss-Newton; exact for kNone.
  Vec2 undistort(const Vec2& xd) const;

  // Camera-frame point to pixel. nullopt when behind the camera (z <= 1e-9).
  std::optional<Vec2> project(const Vec3& p_c) const;
  // Pixel to a ray with z = 1. Fisheye pixels beyond 90 degrees off-axis have no such ray and
  // come back clamped; callers that need the full field of view use bearings (later work).
  Vec3 unproject(const Vec2& uv) const;
  // Jacobian of project() for the undistorted model, d(u,v)/d(p_c); the distortion of the
  // datasets Kestrel tracks on is removed before optimization, so this is what BA needs.
  Mat23 project_jacobian(const Vec3& p_c) const;

  bool in_image(const Vec2& uv, double border = 0.0) const {
    return uv.x() >= border && uv.y() >= border && uv.x() < width - border &&
           uv.y() < height - border;
  }
  Mat3 K() const {
    Mat3 k;
    k << fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0;
    return k;
  }
};

}  // namespace kestrel
