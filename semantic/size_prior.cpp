#include "semantic/size_prior.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace kestrel::semantic {

std::optional<FootprintPrior> footprint_prior(const std::string& label) {
  // Typical sizes (the class's median footprint), not lower bounds: an extent no view could
  // measure is best guessed at the median, which minimizes the expected error, where a lower
  // bound is always short. Lower bounds (3.5 m cars, 0.38 m chairs, 1.4 m sofas) left every
  // one-sided object short by the gap: ugv-loop's cars 0.27-0.37 m off, cafe's chair seen from
  // behind 0.12 m. A compact car (4.3 x 1.8 m), a van or light truck, a city bus, a dining
  // chair (0.5 x 0.5 m), a three-seat sofa (2.0 x 0.9 m), a double bed, a park bench, a
  // four-person table (1.2 x 0.8 m), a fridge, a toilet, a cabin suitcase standing.
  static const std::map<std::string, FootprintPrior> priors = {
      {"car", {4.3, 1.8}},    {"truck", {5.5, 2.0}},        {"bus", {12.0, 2.5}},
      {"chair", {0.5, 0.5}},  {"couch", {2.0, 0.9}},        {"bed", {2.0, 1.4}},
      {"bench", {1.5, 0.5}},  {"dining table", {1.2, 0.8}}, {"refrigerator", {0.7, 0.7}},
      {"toilet", {0.7, 0.4}}, {"suitcase", {0.4, 0.2}},
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
                               const FootprintPrior& prior, const Vec2& cut_towards) {
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
    // The near face stays where it was measured; the far one moves away from the viewers,
    // unless the views were cut along this axis: then the far end was seen and the object
    // grows past the border.
    const double grow = want[a] - size;
    size = want[a];
    const double along = cut_towards.dot(ax[a]);
    const bool cut = std::abs(along) > 0.5 * cut_towards.norm() && cut_towards.norm() > 0.0;
    const double direction = cut ? (along > 0 ? 1.0 : -1.0) : -side[a];
    const Vec2 shift = ax[a] * (direction * grow / 2);
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
