#include "core/camera.hpp"

#include <cmath>

namespace kestrel {

std::string to_string(DistortionModel m) {
  switch (m) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadTan:
      return "radtan";
    case DistortionModel::kEquidistant:
      return "equidistant";
  }
  return "none";
}

std::optional<DistortionModel> distortion_model_from_string(const std::string& name) {
  if (name == "none" || name.empty()) return DistortionModel::kNone;
  if (name == "radtan" || name == "radial-tangential" || name == "plumb_bob" || name == "PinHole" ||
      name == "pinhole") {
    return DistortionModel::kRadTan;
  }
  if (name == "equidistant" || name == "equi" || name == "KannalaBrandt8" || name == "fisheye") {
    return DistortionModel::kEquidistant;
  }
  return std::nullopt;
}

Vec2 PinholeCamera::distort(const Vec2& xn) const {
  const double x = xn.x();
  const double y = xn.y();
  switch (model) {
    case DistortionModel::kNone:
      return xn;
    case DistortionModel::kRadTan: {
      const double r2 = x * x + y * y;
      const double radial = 1.0 + r2 * (dist[0] + r2 * (dist[1] + r2 * dist[4]));
      const double p1 = dist[2];
      const double p2 = dist[3];
      return Vec2(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                  y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
    }
    case DistortionModel::kEquidistant: {
      const double r = std::sqrt(x * x + y * y);
      if (r < 1e-12) return xn;
      const double th = std::atan(r);
      const double th2 = th * th;
      const double thd =
          th * (1.0 + th2 * (dist[0] + th2 * (dist[1] + th2 * (dist[2] + th2 * dist[3]))));
      return xn * (thd / r);
    }
  }
  return xn;
}

Vec2 PinholeCamera::undistort(const Vec2& xd) const {
  if (model == DistortionModel::kNone) return xd;
  // Gauss-Newton on distort(x) = xd with a numeric 2x2 Jacobian and step halving: robust for
  // both models out to the image corners of strongly distorted lenses (EuRoC's k1 = -0.28).
  Vec2 x = xd;
  double err = (distort(x) - xd).squaredNorm();
  for (int it = 0; it < 50 && err > 1e-26; ++it) {
    const Vec2 f = distort(x) - xd;
    constexpr double h = 1e-7;
    Mat2 J;
    J.col(0) = (distort(x + Vec2(h, 0)) - distort(x - Vec2(h, 0))) / (2 * h);
    J.col(1) = (distort(x + Vec2(0, h)) - distort(x - Vec2(0, h))) / (2 * h);
    if (std::fabs(J.determinant()) < 1e-12) break;
    const Vec2 step = J.inverse() * f;
    double scale = 1.0;
    bool improved = false;
    for (int ls = 0; ls < 20; ++ls, scale *= 0.5) {
      const Vec2 candidate = x - scale * step;
      const double e = (distort(candidate) - xd).squaredNorm();
      if (e < err) {
        x = candidate;
        err = e;
        improved = true;
        break;
      }
    }
    if (!improved) break;
  }
  return x;
}

std::optional<Vec2> PinholeCamera::project(const Vec3& p_c) const {
  if (!(p_c.z() > 1e-9)) return std::nullopt;
  const Vec2 xd = distort(Vec2(p_c.x() / p_c.z(), p_c.y() / p_c.z()));
  return Vec2(fx * xd.x() + cx, fy * xd.y() + cy);
}

Vec3 PinholeCamera::unproject(const Vec2& uv) const {
  const Vec2 xn = undistort(Vec2((uv.x() - cx) / fx, (uv.y() - cy) / fy));
  return Vec3(xn.x(), xn.y(), 1.0);
}

Mat23 PinholeCamera::project_jacobian(const Vec3& p) const {
  const double iz = 1.0 / p.z();
  const double iz2 = iz * iz;
  Mat23 J;
  J << fx * iz, 0.0, -fx * p.x() * iz2, 0.0, fy * iz, -fy * p.y() * iz2;
  return J;
}

}  // namespace kestrel
