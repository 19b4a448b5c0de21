#include "semantic/object_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace kestrel::semantic {
namespace {

// The values at fractions lo and hi of the sorted order.
std::pair<double, double> percentiles(std::vector<double>& v, double trim) {
  const std::size_t n = v.size();
  const auto lo = static_cast<std::size_t>(std::floor(trim * static_cast<double>(n - 1)));
  const auto hi = static_cast<std::size_t>(std::ceil((1.0 - trim) * static_cast<double>(n - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(lo), v.end());
  const double a = v[lo];
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(hi), v.end());
  return {a, v[hi]};
}

}  // namespace

UprightBox fit_upright_box(const std::vector<Eigen::Vector3f>& points, double trim) {
  UprightBox box;
  if (points.empty()) return box;
  // The yaw whose box edges the points hug (the closeness criterion of L-shape fitting for
  // vehicles): a car seen end-on and side-on is an L of points, and the smallest trimmed
  // footprint of an L is turned towards its diagonal, where trimming eats the sparse tips of
  // both legs. Principal axes fail the same way, and are arbitrary for near-square footprints
  // (chairs). Distances are floored at a few centimetres so that depth noise does not pick
  // the yaw. A coarse search, then a fine one around it.
  const std::size_t stride = std::max<std::size_t>(1, points.size() / 1500);
  std::vector<Eigen::Vector2d> sample;
  for (std::size_t i = 0; i < points.size(); i += stride)
    sample.push_back(points[i].head<2>().cast<double>());
  std::vector<double> u(sample.size()), v(sample.size()), us_s(sample.size()), vs_s(sample.size());
  auto closeness_at = [&](double yaw) {
    const double c = std::cos(yaw), s = std::sin(yaw);
    for (std::size_t i = 0; i < sample.size(); ++i) {
      u[i] = us_s[i] = c * sample[i].x() + s * sample[i].y();
      v[i] = vs_s[i] = -s * sample[i].x() + c * sample[i].y();
    }
    const auto [u0, u1] = percentiles(us_s, trim);
    const auto [v0, v1] = percentiles(vs_s, trim);
    double score = 0.0;
    for (std::size_t i = 0; i < sample.size(); ++i) {
      const double du = std::min(std::abs(u[i] - u0), std::abs(u1 - u[i]));
      const double dv = std::min(std::abs(v[i] - v0), std::abs(v1 - v[i]));
      score += 1.0 / std::max(std::min(du, dv), 0.05);
    }
    return score;
  };
  double best_yaw = 0.0, best_score = -1.0;
  for (int k = 0; k < 18; ++k) {  // 5 degree steps over a quarter turn
    const double yaw = k * (M_PI / 36.0);
    const double sc = closeness_at(yaw);
    if (sc > best_score) best_score = sc, best_yaw = yaw;
  }
  const double coarse = best_yaw;
  for (int k = -4; k <= 4; ++k) {  // 1 degree steps around it
    const double yaw = coarse + k * (M_PI / 180.0);
    const double sc = closeness_at(yaw);
    if (sc > best_score) best_score = sc, best_yaw = yaw;
  }
  double yaw = best_yaw;
  const Eigen::Vector2d a(std::cos(yaw), std::sin(yaw)), b(-std::sin(yaw), std::cos(yaw));
  std::vector<double> us, vs, z;
  us.reserve(points.size());
  vs.reserve(points.size());
  z.reserve(points.size());
  for (const auto& p : points) {
    const Eigen::Vector2d q = p.head<2>().cast<double>();
    us.push_back(q.dot(a));
    vs.push_back(q.dot(b));
    z.push_back(p.z());
  }
  const auto [u0, u1] = percentiles(us, trim);
  const auto [v0, v1] = percentiles(vs, trim);
  const auto [z0, z1] = percentiles(z, trim);
  const Eigen::Vector2d c = a * (u0 + u1) / 2 + b * (v0 + v1) / 2;
  box.center = Vec3(c.x(), c.y(), (z0 + z1) / 2);
  box.size = Vec3(u1 - u0, v1 - v0, z1 - z0);
  // Report the longer side along the yaw axis, yaw in (-pi/2, pi/2].
  if (box.size.y() > box.size.x()) {
    std::swap(box.size.x(), box.size.y());
    yaw += M_PI / 2;
  }
  if (yaw > M_PI / 2) yaw -= M_PI;
  box.yaw = yaw;
  return box;
}

}  // namespace kestrel::semantic
