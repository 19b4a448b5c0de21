#include "sim/mover_path.hpp"

#include <algorithm>
#include <cmath>

namespace kestrel::sim {

MoverPose mover_pose(const MoverSpec& m, double t) {
  MoverPose out;
  const bool active = t >= m.start && (m.stop < 0 || t < m.stop);
  const double t_end = m.stop < 0 ? t : std::min(t, m.stop);
  const double elapsed = std::max(0.0, t_end - m.start);
  if (m.type == "spin") {
    out.position = m.center;
    out.yaw = m.yaw + m.rate * elapsed;
    out.moving = active && m.rate != 0.0;
    return out;
  }
  std::vector<Vec3> pts = m.path;
  if (m.mode == "loop" && pts.size() > 1) pts.push_back(pts.front());
  std::vector<double> cum{0.0};
  for (std::size_t i = 1; i < pts.size(); ++i)
    cum.push_back(cum.back() + (pts[i] - pts[i - 1]).norm());
  const double total = cum.back();
  double s = m.speed * elapsed;
  bool backwards = false;
  out.moving = active && total > 0.0 && m.speed > 0.0;
  if (total <= 0.0) {
    out.position = pts.front();
    out.yaw = m.yaw;
    return out;
  }
  if (m.mode == "loop") {
    s = std::fmod(s, total);
  } else if (m.mode == "pingpong") {
    s = std::fmod(s, 2.0 * total);
    if (s > total) {
      s = 2.0 * total - s;
      backwards = true;
    }
  } else if (s >= total) {
    s = total;
    out.moving = false;
  }
  std::size_t seg = 1;
  while (seg + 1 < pts.size() && cum[seg] < s) ++seg;
  const Vec3 a = pts[seg - 1], b = pts[seg];
  const double len = cum[seg] - cum[seg - 1];
  const double f = len > 0 ? (s - cum[seg - 1]) / len : 0.0;
  out.position = a + f * (b - a);
  Vec3 dir = backwards ? Vec3(a - b) : Vec3(b - a);
  out.yaw = std::atan2(dir.y(), dir.x()) + m.yaw;
  return out;
}

}  // namespace kestrel::sim
