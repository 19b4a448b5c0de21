#include "semantic/size_prior.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace kestrel::semantic {

std::optional<FootprintPrior> footprint_prior(const std::string& label) {
  // Lower bounds, not typical sizes: a small city car (3.5 x 1.5 m), a narrow side chair
  // (0.38 m), a two-seat sofa (1.4 x 0.75 m), a two-person table (0.6 m), a single bed.
  static const std::map<std::string, FootprintPrior> priors = {
      {"car", {3.5, 1.5}},     {"truck", {4.5, 1.8}},        {"bus", {8.0, 2.3}},
      {"chair", {0.38, 0.38}}, {"couch", {1.4, 0.75}},       {"bed", {1.9, 0.9}},
      {"bench", {0.9, 0.3}},   {"dining table", {0.6, 0.6}}, {"refrigerator", {0.5, 0.5}},
      {"toilet", {0.5, 0.35}}, {"suitcase", {0.35, 0.18}},
  };
  const auto it = priors.find(label);
  if (it == priors.end()) return std::nullopt;
  return it->second;
}

namespace {

// -1: every viewpoint below the box's low face along `axis`, +1: every one above its high
// face, 0: viewed from both sides or from within the slab.
int one_side(const std::vector<Vec3>& viewpoints, const Vec3& centre, const Vec2& axis,
             double half) {
  int side = 0;
  for (const Vec3& p : viewpoints) {
    const double s = (p - centre).head<2>().dot(axis);
    const int here = s < -half ? -1 : (s > half ? 1 : 0);
    if (here == 0 || (side != 0 && here != side)) return 0;
    side = here;
  }
  return side;
}

}  // namespace

UprightBox complete_with_prior(const UprightBox& box, const std::vector<Vec3>& viewpoints,
                               const FootprintPrior& prior) {
  if (viewpoints.empty()) return box;
  const Vec2 ax[2] = {Vec2(std::cos(box.yaw), std::sin(box.yaw)),
                      Vec2(-std::sin(box.yaw), std::cos(box.yaw))};
  const int side[2] = {one_side(viewpoints, box.center, ax[0], box.size.x() / 2),
                       one_side(viewpoints, box.center, ax[1], box.size.y() / 2)};
  double want[2] = {0.0, 0.0};
  if (side[0] != 0 && side[1] != 0) {
    want[0] = box.size.x() >= box.size.y() ? prior.length : prior.width;
    want[1] = box.size.x() >= box.size.y() ? prior.width : prior.length;
  } else {
    for (int a = 0; a < 2; ++a) {
      if (side[a] == 0) continue;
      // The measured side is the length when nearer the prior's length than its width.
      const double other = a == 0 ? box.size.y() : box.size.x();
      want[a] = other > (prior.length + prior.width) / 2 ? prior.width : prior.length;
    }
  }
  UprightBox out = box;
  for (int a = 0; a < 2; ++a) {
    double& size = a == 0 ? out.size.x() : out.size.y();
    if (side[a] == 0 || size >= want[a]) continue;
    // The near face stays where it was measured; the far one moves away from the viewers.
    const double grow = want[a] - size;
    size = want[a];
    const Vec2 shift = ax[a] * (-side[a] * grow / 2);
    out.center.head<2>() += shift;
  }
  // Keep the longer side along the yaw axis, yaw in (-pi/2, pi/2], as fit_upright_box does.
  if (out.size.y() > out.size.x()) {
    std::swap(out.size.x(), out.size.y());
    out.yaw += M_PI / 2;
    if (out.yaw > M_PI / 2) out.yaw -= M_PI;
  }
  return out;
}

}  // namespace kestrel::semantic
