#include "maps/free_space_rule.hpp"

#include <algorithm>
#include <cmath>

namespace kestrel::maps {

ViewFrustum frustum_of(const SE3& T_w_c, const PinholeCamera& camera, double near_depth,
                       double far_range) {
  ViewFrustum v;
  const SE3 T_c_w = T_w_c.inverse();
  v.R_c_w = T_c_w.rotation();
  v.t_c_w = T_c_w.translation();
  v.eye_xy = T_w_c.translation().head<2>();
  v.fx = camera.fx;
  v.fy = camera.fy;
  v.cx = camera.cx;
  v.cy = camera.cy;
  v.width = camera.width;
  v.height = camera.height;
  v.near_depth = near_depth;
  v.far_range = far_range;
  return v;
}

bool in_frustum(const ViewFrustum& v, const Vec3& p_w) {
  return visibility(v, p_w) == Visibility::kInView;
}

Visibility visibility(const ViewFrustum& v, const Vec3& p_w) {
  const Vec3 p = v.R_c_w * p_w + v.t_c_w;
  if (p.z() <= 1e-6 || !(p.squaredNorm() <= v.far_range * v.far_range)) return Visibility::kOutside;
  // Pixel centres run from 0 to width - 1; a pixel covers +-0.5 around its centre.
  const double u = v.fx * p.x() / p.z() + v.cx, w = v.fy * p.y() / p.z() + v.cy;
  if (!(u >= -0.5 && u < v.width - 0.5)) return Visibility::kOutside;
  if (p.z() >= v.near_depth && w >= -0.5 && w < v.height - 0.5) return Visibility::kInView;
  // Within the image's columns, missed only by its rows or the minimum depth: the blind zone
  // right below (or above) a camera.
  return Visibility::kBlindZone;
}

std::vector<std::uint32_t> unobservable_layers(const BandColumns& c,
                                               const std::vector<ViewFrustum>& views) {
  const OccupancyGrid& g = c.grid;
  std::vector<std::uint32_t> out(g.cells().size(), 0);
  const std::uint32_t all = c.all_layers();
  if (all == 0 || c.free_layers.size() != g.cells().size()) return out;
  for (int y = 0; y < g.height(); ++y)
    for (int x = 0; x < g.width(); ++x) {
      const std::size_t i = g.index({x, y});
      if (g.cells()[i] != kFree) continue;
      std::uint32_t unseen = all & ~c.free_layers[i];
      if (unseen == 0) continue;
      const Vec2 xy = g.center_of({x, y});
      std::uint32_t blind = 0;  // layers some view had in its blind zone
      for (const ViewFrustum& v : views) {
        // The cheap test first: a column out of the view's range in x, y.
        if ((v.eye_xy - xy).squaredNorm() > v.far_range * v.far_range) continue;
        for (int l = 0; l < c.layers; ++l) {
          const std::uint32_t bit = std::uint32_t{1} << l;
          if (!(unseen & bit)) continue;
          switch (visibility(v, Vec3(xy.x(), xy.y(), c.layer_center_z(l)))) {
            case Visibility::kInView:
              unseen &= ~bit;
              break;
            case Visibility::kBlindZone:
              blind |= bit;
              break;
            case Visibility::kOutside:
              break;
          }
        }
        if (unseen == 0) break;
      }
      unseen &= blind;
      out[i] = unseen;
    }
  return out;
}

OccupancyGrid resolve_columns(const BandColumns& c, const std::vector<std::uint32_t>* excused) {
  OccupancyGrid g = c.grid;
  const std::uint32_t all = c.all_layers();
  if (all == 0) return g;
  const bool have_layers = c.free_layers.size() == g.cells().size();
  const bool have_excused = excused && excused->size() == g.cells().size();
  for (std::size_t i = 0; i < g.cells().size(); ++i) {
    if (g.cells()[i] != kFree) continue;
    std::uint32_t ok = have_layers ? c.free_layers[i] : 0;
    if (have_excused) ok |= (*excused)[i];
    if ((ok & all) != all) g.cells()[i] = kUnknown;
  }
  return g;
}

OccupancyGrid clear_footprints(const OccupancyGrid& g, const std::vector<Footprint>& footprints,
                               double resolution, bool over_obstacles) {
  const double res = g.empty() ? resolution : g.resolution();
  if (footprints.empty() || !(res > 0.0)) return g;
  // The bounds of the grid and of every disc, snapped to the grid's lattice.
  Vec2 lo = g.origin(), hi = g.origin() + Vec2(g.width() * res, g.height() * res);
  bool first = g.empty();
  for (const Footprint& f : footprints) {
    if (!std::isfinite(f.xy.x()) || !std::isfinite(f.xy.y()) || !(f.radius > 0.0)) continue;
    const Vec2 r = Vec2::Constant(f.radius + res);
    lo = first ? Vec2(f.xy - r) : Vec2(lo.cwiseMin(f.xy - r));
    hi = first ? Vec2(f.xy + r) : Vec2(hi.cwiseMax(f.xy + r));
    first = false;
  }
  if (first) return g;  // no usable footprint on an empty grid
  const Vec2 anchor = g.empty() ? lo : g.origin();
  const Eigen::Vector2i shift =
      ((anchor - lo) / res - Vec2::Constant(1e-9)).array().ceil().cast<int>().cwiseMax(0);
  const Vec2 origin = anchor - shift.cast<double>() * res;
  const int w = std::max(g.width() + shift.x(),
                         static_cast<int>(std::ceil((hi.x() - origin.x()) / res - 1e-9)));
  const int h = std::max(g.height() + shift.y(),
                         static_cast<int>(std::ceil((hi.y() - origin.y()) / res - 1e-9)));
  OccupancyGrid out(w, h, res, origin, kUnknown);
  for (int y = 0; y < g.height(); ++y)
    for (int x = 0; x < g.width(); ++x) out.set({x + shift.x(), y + shift.y()}, g.at({x, y}));
  for (const Footprint& f : footprints) {
    if (!std::isfinite(f.xy.x()) || !std::isfinite(f.xy.y()) || !(f.radius > 0.0)) continue;
    const int r = static_cast<int>(std::ceil(f.radius / res)) + 1;
    const auto c = out.cell_of(f.xy);
    if (!c) continue;
    for (int dy = -r; dy <= r; ++dy)
      for (int dx = -r; dx <= r; ++dx) {
        const GridCell n{c->x + dx, c->y + dy};
        if (!out.contains(n) || (out.at(n) != kUnknown && !over_obstacles)) continue;
        if ((out.center_of(n) - f.xy).norm() <= f.radius) out.set(n, kFree);
      }
  }
  return out;
}

}  // namespace kestrel::maps
