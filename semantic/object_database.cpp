#include "semantic/object_database.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <string_view>
#include <unordered_set>

#include "core/error.hpp"
#include "semantic/euclidean_clusters.hpp"
#include "semantic/size_prior.hpp"

namespace kestrel::semantic {
namespace {

struct PixelBox {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  double area() const { return std::max(0.0, x1 - x0) * std::max(0.0, y1 - y0); }
};

double iou(const PixelBox& a, const PixelBox& b) {
  const double w = std::min(a.x1, b.x1) - std::max(a.x0, b.x0);
  const double h = std::min(a.y1, b.y1) - std::max(a.y0, b.y0);
  if (w <= 0 || h <= 0) return 0.0;
  const double inter = w * h;
  return inter / (a.area() + b.area() - inter);
}

PixelBox to_box(const detect::Detection& d) { return {d.x_min, d.y_min, d.x_max, d.y_max}; }

// A lattice pixel (sampled every `stride`) whose cell touches the box.
bool inside(const PixelBox& b, const Eigen::Vector2i& p, int stride) {
  return p.x() + stride > b.x0 && p.x() < b.x1 && p.y() + stride > b.y0 && p.y() < b.y1;
}

double footprint(const UprightBox& b) { return std::max(b.size.x(), b.size.y()); }

// Its class's typical length where it has one, else its own: the fused box of an object caught
// early in a move is smeared along its path, and gates from that size would grow with the move.
double typical_length(const SemanticObject& o) {
  const auto prior = footprint_prior(o.label);
  return prior ? prior->length : footprint(o.box);
}

// Labels a detector gives one object by turns: YOLO calls a parked pickup a car in one view and
// a truck in the next (ugv-loop). Such entries are one object, under the label seen most.
bool confusable(const std::string& a, const std::string& b) {
  if (a == b) return true;
  static const std::array<std::string_view, 3> kVehicles = {"car", "truck", "bus"};
  const auto in = [](const std::string& l) {
    return std::find(kVehicles.begin(), kVehicles.end(), l) != kVehicles.end();
  };
  return in(a) && in(b);
}

void vote(std::vector<std::pair<std::string, double>>& votes, const std::string& label,
          double score) {
  auto it =
      std::find_if(votes.begin(), votes.end(), [&](const auto& v) { return v.first == label; });
  if (it == votes.end()) {
    votes.emplace_back(label, score);
  } else {
    it->second += score;
  }
}

const std::string& elected(const std::vector<std::pair<std::string, double>>& votes,
                           const std::string& fallback) {
  if (votes.empty()) return fallback;
  return std::max_element(votes.begin(), votes.end(),
                          [](const auto& x, const auto& y) { return x.second < y.second; })
      ->first;
}

// Centres closer than `factor` x the larger footprint (labels are compared by the caller).
bool same_object(const UprightBox& a, const UprightBox& b, double factor) {
  const double dist = (a.center - b.center).head<2>().norm();
  return dist < factor * std::max({footprint(a), footprint(b), 0.3});
}

// The image box of an object's upright box seen from T_w_c, clipped to the image; false when
// behind the camera. `whole`, when given, says whether no clipping was needed.
bool project_box(const UprightBox& b, const SE3& T_w_c, const PinholeCamera& cam, PixelBox& out,
                 bool* whole = nullptr) {
  const SE3 T_c_w = T_w_c.inverse();
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  out = {1e9, 1e9, -1e9, -1e9};
  for (int k = 0; k < 8; ++k) {
    const double u = (k & 1 ? 0.5 : -0.5) * b.size.x(), v = (k & 2 ? 0.5 : -0.5) * b.size.y();
    const Vec3 pw =
        b.center + Vec3(c * u - s * v, s * u + c * v, (k & 4 ? 0.5 : -0.5) * b.size.z());
    const Vec3 pc = T_c_w * pw;
    if (pc.z() < 0.1) return false;
    const auto uv = cam.project(pc);
    if (!uv) return false;
    out.x0 = std::min(out.x0, uv->x());
    out.y0 = std::min(out.y0, uv->y());
    out.x1 = std::max(out.x1, uv->x());
    out.y1 = std::max(out.y1, uv->y());
  }
  if (whole) *whole = out.x0 >= 0 && out.y0 >= 0 && out.x1 <= cam.width && out.y1 <= cam.height;
  out.x0 = std::max(out.x0, 0.0);
  out.y0 = std::max(out.y0, 0.0);
  out.x1 = std::min(out.x1, static_cast<double>(cam.width));
  out.y1 = std::min(out.y1, static_cast<double>(cam.height));
  return out.area() > 0;
}

std::uint64_t voxel_key(const Eigen::Vector3f& p, double voxel) {
  auto q = [&](float v) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v / voxel)) +
                                      (1 << 20)) &
           0x1FFFFF;
  };
  return q(p.x()) | (q(p.y()) << 21) | (q(p.z()) << 42);
}

// Share of the cells of `a` that `b` occupies too.
double overlap(const std::unordered_set<std::uint64_t>& a,
               const std::unordered_set<std::uint64_t>& b) {
  if (a.empty()) return 0.0;
  int shared = 0;
  for (std::uint64_t k : a) shared += b.count(k) > 0;
  return static_cast<double>(shared) / static_cast<double>(a.size());
}

std::vector<Eigen::Vector3f> thin(const std::vector<Eigen::Vector3f>& pts, double voxel,
                                  int max_points) {
  std::unordered_set<std::uint64_t> seen;
  std::vector<Eigen::Vector3f> out;
  for (const auto& p : pts)
    if (seen.insert(voxel_key(p, voxel)).second) out.push_back(p);
  if (static_cast<int>(out.size()) > max_points) {
    std::vector<Eigen::Vector3f> kept;
    const double step = static_cast<double>(out.size()) / max_points;
    for (int i = 0; i < max_points; ++i) kept.push_back(out[static_cast<std::size_t>(i * step)]);
    out.swap(kept);
  }
  return out;
}

}  // namespace

double SemanticObject::confidence() const {
  if (observations <= 0) return 0.0;
  return (score_sum / observations) * (1.0 - std::exp(-observations / 3.0));
}

ObjectDatabase::ObjectDatabase(const ObjectDatabaseOptions& options) : options_(options) {}

void ObjectDatabase::update_floor(const ObjectKeyframe& kf) {
  // The floor is the lowest horizontal surface holding a good share of what the camera sees
  // (the world is gravity-aligned, z up). A running average over keyframes smooths the noise.
  const Image& d = *kf.depth;
  const Mat3 R = kf.T_w_c.rotation();
  const Vec3 t = kf.T_w_c.translation();
  std::vector<double> z;
  for (int v = 0; v < d.height; v += 8) {
    const auto* row = d.row<std::uint16_t>(v);
    for (int u = 0; u < d.width; u += 8) {
      const double depth = row[u] / kf.depth_scale;
      if (row[u] == 0 || depth < options_.min_depth || depth > 4.0) continue;
      z.push_back((R * (kf.camera.unproject(Vec2(u, v)) * depth) + t).z());
    }
  }
  if (z.size() < 100) return;
  std::sort(z.begin(), z.end());
  // Slide a 6 cm window up from the bottom; the first holding 10% of the samples is the floor.
  const std::size_t need = z.size() / 10;
  for (std::size_t i = 0, j = 0; i < z.size(); ++i) {
    while (j < z.size() && z[j] < z[i] + 0.06) ++j;
    if (j - i >= need) {
      const double est = z[i + (j - i) / 2];
      // Only a surface below the camera can be the floor.
      if (est > t.z() - 0.3) return;
      floor_z_ = (floor_z_ * floor_samples_ + est) / (floor_samples_ + 1);
      floor_samples_ = std::min(floor_samples_ + 1, 50);
      return;
    }
  }
}

std::vector<ObjectDatabase::Measurement> ObjectDatabase::measure_all(
    const ObjectKeyframe& kf) const {
  const Image& d = *kf.depth;
  const int s = std::max(1, options_.pixel_stride);
  const Mat3 R = kf.T_w_c.rotation();
  const Vec3 t = kf.T_w_c.translation();
  const bool masked =
      kf.static_mask && kf.static_mask->size() == static_cast<std::size_t>(d.width) * d.height;
  const int r = std::max(0, options_.smooth_radius);

  // Boxes worth measuring.
  std::vector<const detect::Detection*> boxes;
  for (const detect::Detection& det : kf.static_boxes) {
    const double w = std::min<double>(det.x_max, d.width) - std::max<double>(det.x_min, 0.0);
    const double h = std::min<double>(det.y_max, d.height) - std::max<double>(det.y_min, 0.0);
    if (w <= 0 || h <= 0 || w * h < options_.min_box_pixels) continue;
    // A box cut by the image border shows part of the object (optional: fusion of the parts
    // across views usually recovers the whole).
    const double margin = options_.border_margin;
    if (margin >= 0 && (det.x_min <= margin || det.y_min <= margin ||
                        det.x_max >= d.width - margin || det.y_max >= d.height - margin))
      continue;
    boxes.push_back(&det);
  }
  if (boxes.empty()) return {};

  // The camera point of pixel (u, v) on a surface that may belong to an object: a valid depth
  // in range, not a mover, above the floor band.
  auto surface_point = [&](int u, int v, Eigen::Vector3f& out) {
    const auto* row = d.row<std::uint16_t>(v);
    if (row[u] == 0) return false;
    if (masked && (*kf.static_mask)[static_cast<std::size_t>(v) * d.width + u] == 0) return false;
    const double z0 = row[u] / kf.depth_scale;
    if (z0 < options_.min_depth || z0 > options_.max_depth) return false;
    // Depth noise is per pixel: averaging the neighbours on the same surface (within a few
    // sigma) divides it by up to 2r+1 before the geometry sees it.
    const double tol = (2.5 * options_.depth_noise_z2 * z0 * z0 + 0.02) * kf.depth_scale;
    double sum = 0.0;
    int n = 0;
    for (int yy = std::max(0, v - r); yy <= std::min(d.height - 1, v + r); ++yy) {
      const auto* nrow = d.row<std::uint16_t>(yy);
      for (int xx = std::max(0, u - r); xx <= std::min(d.width - 1, u + r); ++xx) {
        if (nrow[xx] == 0 || std::abs(static_cast<double>(nrow[xx]) - row[u]) > tol) continue;
        sum += nrow[xx];
        ++n;
      }
    }
    const double z = sum / n / kf.depth_scale;
    const Vec3 pc = kf.camera.unproject(Vec2(u, v)) * z;
    if (has_floor() && (R * pc + t).z() < floor_z_ + floor_cut(z)) return false;
    out = pc.cast<float>();
    return true;
  };

  // Depth points on one stride-aligned lattice over the union of the boxes, so that a pixel
  // seen by two overlapping boxes is one point and belongs to at most one of their clusters.
  std::vector<std::uint8_t> visited(static_cast<std::size_t>(d.width) * d.height, 0);
  std::vector<Eigen::Vector3f> pts;
  std::vector<Eigen::Vector2i> px;
  for (const detect::Detection* det : boxes) {
    const int x0 = std::clamp(static_cast<int>(std::floor(det->x_min)), 0, d.width);
    const int x1 = std::clamp(static_cast<int>(std::ceil(det->x_max)), 0, d.width);
    const int y0 = std::clamp(static_cast<int>(std::floor(det->y_min)), 0, d.height);
    const int y1 = std::clamp(static_cast<int>(std::ceil(det->y_max)), 0, d.height);
    for (int v = (y0 + s - 1) / s * s; v < y1; v += s) {
      for (int u = (x0 + s - 1) / s * s; u < x1; u += s) {
        const std::size_t idx = static_cast<std::size_t>(v) * d.width + u;
        if (visited[idx]) continue;
        visited[idx] = 1;
        Eigen::Vector3f pc;
        if (!surface_point(u, v, pc)) continue;
        pts.push_back(pc);
        px.emplace_back(u, v);
      }
    }
  }
  if (static_cast<int>(pts.size()) < options_.min_cluster_points) return {};
  auto clusters = euclidean_clusters(pts, options_.cluster_tolerance, options_.min_cluster_points);

  // Every cluster's whole image footprint (not clipped to one box): an occluder in front of a
  // larger box spills out of that box, so it fits its own box better than the one behind it.
  struct ClusterInfo {
    PixelBox footprint{1e9, 1e9, -1e9, -1e9};
    double depth = 0.0, rms = 0.0;
    double iou = 0.0;  // with the box being matched
  };
  auto describe = [&](const std::vector<int>& members) {
    ClusterInfo ci;
    std::vector<float> depth;
    depth.reserve(members.size());
    for (int i : members) {
      ci.footprint.x0 = std::min<double>(ci.footprint.x0, px[i].x());
      ci.footprint.y0 = std::min<double>(ci.footprint.y0, px[i].y());
      ci.footprint.x1 = std::max<double>(ci.footprint.x1, px[i].x() + s);
      ci.footprint.y1 = std::max<double>(ci.footprint.y1, px[i].y() + s);
      depth.push_back(pts[i].z());
    }
    std::nth_element(depth.begin(), depth.begin() + depth.size() / 2, depth.end());
    ci.depth = depth[depth.size() / 2];
    double sq = 0.0;
    for (float z : depth) sq += (z - ci.depth) * (z - ci.depth);
    ci.rms = std::sqrt(sq / depth.size());
    return ci;
  };
  std::vector<ClusterInfo> info;
  for (const auto& c : clusters) info.push_back(describe(c));

  // One cluster per box and one box per cluster. Smaller boxes choose first: where two boxes
  // overlap and both see the same nearest surface, it is the object of the smaller box in front
  // of the larger one (a chair before its table), and a box's object is the nearest cluster
  // among those whose footprint fits the box nearly as well as the best, since the object
  // occludes what lies behind it (a wall around a chair fills the box too). The first pass
  // compares whole footprints, so that an occluder spilling out of a box is not taken for that
  // box's object; the second lets the remaining boxes take the part of a cluster inside them
  // (objects that touch, a chair tucked against its table, are one cluster).
  std::vector<std::size_t> order(boxes.size());
  for (std::size_t b = 0; b < order.size(); ++b) order[b] = b;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    return to_box(*boxes[x]).area() < to_box(*boxes[y]).area();
  });
  // A box's own region: where no other box overlaps it. A surface seen there is its object (or
  // what lies behind it); a cluster a box sees only where another box overlaps it belongs to
  // that box's object, seen through this one: a table in front of the chair tucked behind it,
  // whose box nearly covers the chair's. Such a box takes only clusters seen in its own region,
  // when that region is a fair share of the box and shows surfaces at all (a cup on a table
  // has none; the floor band leaves none under a table).
  std::vector<int> own_box(px.size(), -1);  // the one box a point lies in, else -1
  std::vector<int> own_points(boxes.size(), 0);
  for (std::size_t i = 0; i < px.size(); ++i) {
    for (std::size_t b = 0; b < boxes.size(); ++b) {
      if (!inside(to_box(*boxes[b]), px[i], s)) continue;
      own_box[i] = own_box[i] == -1 ? static_cast<int>(b) : -2;
    }
    if (own_box[i] >= 0) ++own_points[static_cast<std::size_t>(own_box[i])];
  }
  std::vector<bool> judged_by_own_region(boxes.size(), false);
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    const PixelBox box = to_box(*boxes[b]);
    int own = 0, all = 0;
    for (int v = static_cast<int>(box.y0) / s * s; v < box.y1; v += s) {
      for (int u = static_cast<int>(box.x0) / s * s; u < box.x1; u += s) {
        const Eigen::Vector2i p(u, v);
        if (!inside(box, p, s)) continue;
        ++all;
        bool other = false;
        for (std::size_t o = 0; o < boxes.size() && !other; ++o)
          other = o != b && inside(to_box(*boxes[o]), p, s);
        own += other ? 0 : 1;
      }
    }
    judged_by_own_region[b] = all > 0 && own < all && own >= options_.min_own_region_share * all &&
                              own_points[b] >= options_.min_own_region_surface;
  }
  std::vector<bool> used(clusters.size(), false);
  std::vector<std::vector<int>> chosen(boxes.size());
  std::vector<ClusterInfo> chosen_info(boxes.size());
  const auto in_box = [&](std::size_t c, const PixelBox& box) {
    std::vector<int> in;
    for (int i : clusters[c])
      if (inside(box, px[i], s)) in.push_back(i);
    return in;
  };
  // Cluster c's points seen in box b's own region.
  const auto seen_in_own_region = [&](std::size_t c, std::size_t b) {
    int seen = 0;
    for (int i : clusters[c]) seen += own_box[static_cast<std::size_t>(i)] == static_cast<int>(b);
    return seen;
  };
  // A box took cluster c's part inside it: the rest stays for the other boxes.
  const auto keep_rest = [&](std::size_t c, const PixelBox& box) {
    std::vector<int> rest;
    for (int i : clusters[c])
      if (!inside(box, px[i], s)) rest.push_back(i);
    if (static_cast<int>(rest.size()) >= options_.min_cluster_points) {
      info[c] = describe(rest);
      clusters[c] = std::move(rest);
    } else {
      used[c] = true;
    }
  };
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t b : order) {
      if (!chosen[b].empty()) continue;
      const PixelBox box = to_box(*boxes[b]);
      std::vector<std::pair<std::size_t, ClusterInfo>> cand;
      double top = 0.0;
      for (std::size_t c = 0; c < clusters.size(); ++c) {
        if (used[c]) continue;
        ClusterInfo ci = info[c];
        if (pass == 1) {
          const std::vector<int> in = in_box(c, box);
          if (static_cast<int>(in.size()) < options_.min_cluster_points) continue;
          ci = describe(in);
        }
        if (ci.rms > options_.max_depth_rms) continue;
        ci.iou = iou(ci.footprint, box);
        if (ci.iou < options_.min_iou) continue;
        if (judged_by_own_region[b] && seen_in_own_region(c, b) < options_.min_own_region_points)
          continue;
        top = std::max(top, ci.iou);
        cand.emplace_back(c, ci);
      }
      const std::pair<std::size_t, ClusterInfo>* pick = nullptr;
      for (const auto& c : cand)
        if (c.second.iou >= top - options_.iou_tie &&
            (!pick || c.second.depth < pick->second.depth))
          pick = &c;
      if (!pick) continue;
      const std::size_t c = pick->first;
      chosen[b] = in_box(c, box);
      chosen_info[b] = describe(chosen[b]);
      chosen_info[b].iou = pick->second.iou;
      keep_rest(c, box);
    }
  }

  // A box judged by its own region that found no cluster: its object may be cut in parts by
  // what hides its middle (a chair behind its table: the backrest above the table top, the
  // legs below it, the seat hidden, two clusters). The cluster seen in its own region anchors
  // it; the parts inside the box of the other clusters at about its depth (as deep as an object
  // is wide) join it, and together they must fit the box.
  for (std::size_t b : order) {
    if (!options_.join_parts || !chosen[b].empty() || !judged_by_own_region[b]) continue;
    const PixelBox box = to_box(*boxes[b]);
    std::size_t anchor = clusters.size();
    int best_own = options_.min_own_region_points - 1;
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      if (used[c]) continue;
      const int seen = seen_in_own_region(c, b);
      if (seen > best_own) best_own = seen, anchor = c;
    }
    if (anchor == clusters.size()) continue;
    const double z0 = describe(in_box(anchor, box)).depth;
    const double width_m = (box.x1 - box.x0) * z0 / kf.camera.fx;
    const double keep = std::max(options_.min_depth_extent, options_.depth_extent_factor * width_m);
    std::vector<std::size_t> parts;
    std::vector<int> group;
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      if (used[c]) continue;
      const std::vector<int> in = in_box(c, box);
      if (in.empty() || (c != anchor && static_cast<int>(in.size()) < options_.min_cluster_points))
        continue;
      if (c != anchor && std::abs(describe(in).depth - z0) > keep) continue;
      parts.push_back(c);
      group.insert(group.end(), in.begin(), in.end());
    }
    if (parts.size() < 2) continue;  // one cluster alone was judged by the passes above
    ClusterInfo gi = describe(group);
    gi.iou = iou(gi.footprint, box);
    if (gi.iou < options_.min_iou || gi.rms > options_.max_depth_rms) continue;
    chosen[b] = group;
    chosen_info[b] = gi;
    for (std::size_t c : parts) keep_rest(c, box);
  }

  // Whether the surface a box's cluster lies on goes on past an edge of the box that is not the
  // image border, on most of that edge: the detector bounds its object, so a cluster that does
  // not end at the box is a part of something larger seen through the box (a stall in front of
  // a table it hides). Pixels just outside the box count when they hold a surface point at the
  // depth of the cluster's edge point beside them and lie in no other static box (a chair tucked
  // against its table continues into the table's box).
  auto continues_past_box = [&](const PixelBox& box, const std::vector<int>& members) {
    const int x0 = static_cast<int>(std::floor(box.x0)), x1 = static_cast<int>(std::ceil(box.x1));
    const int y0 = static_cast<int>(std::floor(box.y0)), y1 = static_cast<int>(std::ceil(box.y1));
    // Edges: 0 left, 1 right, 2 top, 3 bottom; the lattice line just outside each.
    const int out_line[4] = {(x0 - 1) / s * s, (x1 + s - 1) / s * s, (y0 - 1) / s * s,
                             (y1 + s - 1) / s * s};
    const bool interior[4] = {x0 >= s, x1 + s <= d.width - 1, y0 >= s, y1 + s <= d.height - 1};
    int cont[4] = {0, 0, 0, 0};
    auto in_other_box = [&](int u, int v) {
      for (const detect::Detection& o : kf.static_boxes) {
        const PixelBox ob = to_box(o);
        if (ob.x0 == box.x0 && ob.y0 == box.y0 && ob.x1 == box.x1 && ob.y1 == box.y1) continue;
        if (u >= ob.x0 && u < ob.x1 && v >= ob.y0 && v < ob.y1) return true;
      }
      return false;
    };
    for (int i : members) {
      const int u = px[i].x(), v = px[i].y();
      const bool at[4] = {u < x0 + 2 * s, u + 2 * s >= x1, v < y0 + 2 * s, v + 2 * s >= y1};
      for (int e = 0; e < 4; ++e) {
        if (!interior[e] || !at[e]) continue;
        const int uo = e < 2 ? out_line[e] : u, vo = e < 2 ? v : out_line[e];
        if (uo < 0 || uo >= d.width || vo < 0 || vo >= d.height || in_other_box(uo, vo)) continue;
        Eigen::Vector3f q;
        if (!surface_point(uo, vo, q)) continue;
        const double z = pts[i].z();
        cont[e] += std::abs(q.z() - z) <
                   options_.cluster_tolerance + 3.0 * options_.depth_noise_z2 * z * z;
      }
    }
    // Share of the edge's length: two lattice lines along it.
    const double lines[4] = {2.0 * (y1 - y0) / s, 2.0 * (y1 - y0) / s, 2.0 * (x1 - x0) / s,
                             2.0 * (x1 - x0) / s};
    for (int e = 0; e < 4; ++e)
      if (cont[e] >= 4 && cont[e] >= options_.min_edge_continuation * lines[e]) return true;
    return false;
  };

  std::vector<Measurement> out;
  const Eigen::Matrix3f Rf = R.cast<float>();
  const Eigen::Vector3f tf = t.cast<float>();
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    if (chosen[b].empty()) continue;
    const detect::Detection& det = *boxes[b];
    const PixelBox box = to_box(det);
    const ClusterInfo& ci = chosen_info[b];
    // A cluster can hold what touches the object (a table behind a tucked-in chair); an object
    // is about as deep as it is wide, so points much farther than that from the cluster's
    // median depth belong to something else. The detection bounds the object in the image.
    const double width_m = (box.x1 - box.x0) * ci.depth / kf.camera.fx;
    const double keep = std::max(options_.min_depth_extent, options_.depth_extent_factor * width_m);
    // Only where another static box claims the pixel, though: an object seen end-on (a bench,
    // a parked car) is far deeper than its box is wide, and nothing else is there to explain
    // its far end.
    auto in_other_box = [&](const Eigen::Vector2i& p) {
      for (std::size_t o = 0; o < boxes.size(); ++o)
        if (o != b && inside(to_box(*boxes[o]), p, s)) return true;
      return false;
    };
    std::vector<Eigen::Vector3f> members;
    for (int i : chosen[b])
      if (std::abs(pts[i].z() - ci.depth) <= keep ||
          (options_.extend_past_depth_extent && !in_other_box(px[i])))
        members.push_back(pts[i]);
    if (static_cast<int>(members.size()) < options_.min_cluster_points) continue;
    Measurement m;
    m.label = det.label;
    m.score = det.score;
    m.depth = ci.depth;
    m.points_c = thin(members, options_.point_voxel, options_.max_points_per_observation);
    for (const auto& p : m.points_c) m.points_w.push_back(Rf * p + tf);
    m.box = fit_upright_box(m.points_w);
    // A box at the image's left or right border: the object goes on out of view, across the
    // border's ray (turned a quarter left or right of it, seen from above with z up).
    const double v_mid = 0.5 * (det.y_min + det.y_max);
    auto across_border = [&](double u, double turn) {
      const Vec2 ray = (R * kf.camera.unproject(Vec2(u, v_mid))).head<2>();
      return ray.norm() > 1e-9 ? Vec2(-turn * ray.y(), turn * ray.x()) / ray.norm()
                               : Vec2::Zero().eval();
    };
    // A box touching both side borders (an object filling the width) says nothing of where
    // the rest is: the two directions would add up to one pointing back at the camera.
    const bool cut_left = det.x_min <= 1.0, cut_right = det.x_max >= d.width - 1.0;
    if (cut_left != cut_right)
      m.cut_towards = cut_left ? across_border(0.0, 1.0) : across_border(d.width - 1.0, -1.0);
    if (options_.size_priors) {
      if (const auto prior = footprint_prior(m.label)) {
        m.box = complete_with_prior(m.box, {kf.T_w_c.translation()}, *prior, m.cut_towards);
        // Far longer than its class: several objects taken for one (the front of a table
        // between two chairs, in a chair's box with no table box beside it).
        if (std::max(m.box.size.x(), m.box.size.y()) >
            options_.max_length_over_prior * prior->length)
          continue;
      }
    }
    m.cut = continues_past_box(box, chosen[b]);
    out.push_back(std::move(m));
  }
  return out;
}

std::vector<Eigen::Vector3f> ObjectDatabase::world_points(const Entry& e) const {
  std::vector<Eigen::Vector3f> pts;
  for (const Observation& o : e.views) {
    const auto it = keyframe_poses_.find(o.keyframe_id);
    if (it == keyframe_poses_.end()) continue;
    const Eigen::Matrix3f R = it->second.rotation().cast<float>();
    const Eigen::Vector3f t = it->second.translation().cast<float>();
    for (const auto& p : o.points_c) pts.push_back(R * p + t);
  }
  return pts;
}

std::unordered_set<std::uint64_t> ObjectDatabase::voxels_of(
    const std::vector<Eigen::Vector3f>& pts_w) const {
  std::unordered_set<std::uint64_t> out;
  for (const auto& p : pts_w) out.insert(voxel_key(p, options_.overlap_voxel));
  return out;
}

void ObjectDatabase::refit(Entry& e) const {
  const auto pts = world_points(e);
  e.voxels = voxels_of(pts);
  if (pts.empty()) return;
  UprightBox b = fit_upright_box(pts);
  if (options_.size_priors) {
    if (const auto prior = footprint_prior(e.object.label)) {
      std::vector<Vec3> viewpoints;
      for (const Observation& o : e.views) {
        const auto it = keyframe_poses_.find(o.keyframe_id);
        if (it != keyframe_poses_.end()) viewpoints.push_back(it->second.translation());
      }
      // Cut in a third of its views or more, mostly one way: the hidden part is past that
      // border (views cut left and right of the object cancel out).
      Vec2 cut_towards = Vec2::Zero();
      int cut_views = 0;
      for (const Observation& o : e.views) {
        const auto it = keyframe_poses_.find(o.keyframe_id);
        if (it == keyframe_poses_.end() || o.cut_c.isZero()) continue;
        cut_towards += (it->second.rotation() * o.cut_c).head<2>();
        ++cut_views;
      }
      const bool cut = cut_views > 0 && 3 * cut_views >= static_cast<int>(e.views.size()) &&
                       cut_towards.norm() >= 0.5 * cut_views;
      b = complete_with_prior(b, viewpoints, *prior, cut ? cut_towards : Vec2::Zero());
    }
  }
  // Objects standing on the floor reach down to it: the floor band was cut from the points.
  const double bottom = b.center.z() - b.size.z() / 2;
  const double top = b.center.z() + b.size.z() / 2;
  if (has_floor() && bottom < floor_z_ + floor_cut(e.mean_depth) + 0.1 && top > floor_z_) {
    b.center.z() = (floor_z_ + top) / 2;
    b.size.z() = top - floor_z_;
  }
  e.object.box = b;
}

int ObjectDatabase::merge_duplicates() {
  int merged = 0;
  for (bool again = true; again;) {
    again = false;
    for (auto a = entries_.begin(); a != entries_.end() && !again; ++a) {
      for (auto b = std::next(a); b != entries_.end(); ++b) {
        if (!confusable(a->second.object.label, b->second.object.label)) continue;
        const bool relabel = a->second.object.label != b->second.object.label;
        if (relabel && (a->second.object.moving || b->second.object.moving)) continue;
        // A moving object passing another of its kind is still two objects; but one that
        // appeared, still, where the moving one went while it moved is where it stopped (seen
        // there first after a gap in the views).
        if (a->second.object.moving || b->second.object.moving) {
          if (a->second.object.moving == b->second.object.moving) continue;
          const auto mover = a->second.object.moving ? a : b;
          const auto still = a->second.object.moving ? b : a;
          if (still->second.object.first_seen < mover->second.still_since ||
              !same_object(mover->second.object.box, still->second.object.box,
                           options_.merge_factor))
            continue;
          entries_.erase(mover);
          ++merged;
          again = true;
          break;
        }
        const auto& va = a->second.voxels;
        const auto& vb = b->second.voxels;
        const double shared = va.size() < vb.size() ? overlap(va, vb) : overlap(vb, va);
        if (!same_object(a->second.object.box, b->second.object.box, options_.merge_factor) &&
            shared < options_.min_overlap)
          continue;
        Entry& keep = a->second;
        Entry& gone = b->second;
        for (const auto& [label, score] : gone.votes) vote(keep.votes, label, score);
        keep.object.label = elected(keep.votes, keep.object.label);
        for (auto& v : gone.views) keep.views.push_back(std::move(v));
        keep.mean_depth = std::max(keep.mean_depth, gone.mean_depth);
        keep.object.observations += gone.object.observations;
        keep.object.whole_observations += gone.object.whole_observations;
        keep.object.score_sum += gone.object.score_sum;
        keep.object.first_seen = std::min(keep.object.first_seen, gone.object.first_seen);
        keep.object.last_seen = std::max(keep.object.last_seen, gone.object.last_seen);
        refit(keep);
        entries_.erase(b);
        ++merged;
        again = true;
        break;
      }
      if (again) break;  // `a` may be gone: start over
    }
  }
  return merged;
}

void ObjectDatabase::fuse(Entry& e, HeldView&& v) const {
  SemanticObject& o = e.object;
  ++o.observations;
  o.whole_observations += v.cut ? 0 : 1;
  o.score_sum += v.score;
  o.first_seen = std::min(o.first_seen, v.stamp);
  o.last_seen = std::max(o.last_seen, v.stamp);
  if (!v.label.empty()) {
    vote(e.votes, v.label, v.score);
    o.label = elected(e.votes, o.label);
  }
  e.mean_depth += (v.depth - e.mean_depth) / o.observations;
  e.views.push_back(std::move(v.view));
  if (static_cast<int>(e.views.size()) > options_.max_observations_kept)
    e.views.erase(e.views.begin());
  refit(e);
}

ObjectDatabase::MotionStep ObjectDatabase::track_motion(Entry& e, const Vec2& at, Timestamp stamp,
                                                        ObjectUpdateStats& stats) const {
  const UprightBox& b = e.object.box;
  const double move = std::max(options_.min_move, options_.move_factor * typical_length(e.object));
  if (e.object.moving) {
    if ((at - e.still_at).norm() <= options_.still_factor * move) return MotionStep::kFuse;
    e.still_at = at;
    e.still_since = stamp;
    return MotionStep::kRestart;
  }
  const double away = (at - b.center.head<2>()).norm();
  // A streak that has not proved a move within move_window was views, not a move: partial views
  // of a static object can sit off its centre for as long as the camera looks from there. What
  // it held goes into the object after all.
  auto release = [&] {
    e.displaced = 0;
    for (HeldView& h : e.held) fuse(e, std::move(h));
    e.held.clear();
  };
  if (e.displaced > 0 && to_seconds(stamp - e.displaced_since) > options_.move_window) {
    release();
    return MotionStep::kFuse;
  }
  if (static_cast<int>(e.views.size()) < options_.min_observations || away <= move) {
    release();
    return MotionStep::kFuse;
  }
  // Held out of the object until the streak decides: fused, the first steps of a move would
  // drag a young object's centre along, and it would never look displaced.
  if (e.displaced++ == 0) {
    e.displaced_since = stamp;
    e.displaced_away = away;
  }
  e.displaced_last = at;
  // Walking away: each streak farther from where it stood, not a view off its centre that a
  // moving camera slides about (market's potted plant, half hidden: 0.55 then 0.38 m off).
  if (e.displaced < options_.move_streak || away - e.displaced_away < options_.move_travel)
    return MotionStep::kHold;
  e.object.moving = true;
  e.displaced = 0;
  e.still_at = at;
  e.still_since = stamp;
  ++stats.started_moving;
  return MotionStep::kRestart;
}

ObjectDatabase::Sighting ObjectDatabase::look_for(const Entry& e, const ObjectKeyframe& kf) const {
  const UprightBox& b = e.object.box;
  PixelBox pb;
  bool whole = false;
  if (!project_box(b, kf.T_w_c, kf.camera, pb, &whole) || !whole ||
      pb.area() < options_.min_box_pixels)
    return Sighting::kUnknown;
  const SE3 T_c_w = kf.T_w_c.inverse();
  const double centre_depth = (T_c_w * b.center).z();
  // Past the sensor's range an empty reading says nothing.
  if (centre_depth > options_.max_depth - options_.absent_range_margin) return Sighting::kUnknown;
  for (const detect::Detection& det : kf.static_boxes)
    if (confusable(det.label, e.object.label) && iou(pb, to_box(det)) > options_.moving_iou)
      return Sighting::kSeen;
  const Image& d = *kf.depth;
  const bool masked =
      kf.static_mask && kf.static_mask->size() == static_cast<std::size_t>(d.width) * d.height;
  const double c = std::cos(b.yaw), sn = std::sin(b.yaw);
  const double reach = 0.5 * std::hypot(b.size.x(), b.size.y());
  const double noise = options_.depth_noise_z2 * centre_depth * centre_depth;
  const double grow = options_.absent_margin + 2.0 * noise;
  int n = 0, support = 0, hidden = 0;
  const int step = 4;
  for (int v = static_cast<int>(pb.y0); v < static_cast<int>(pb.y1); v += step) {
    const auto* row = d.row<std::uint16_t>(v);
    for (int u = static_cast<int>(pb.x0); u < static_cast<int>(pb.x1); u += step) {
      if (masked && (*kf.static_mask)[static_cast<std::size_t>(v) * d.width + u] == 0) {
        ++n, ++hidden;  // a mover in front
        continue;
      }
      if (row[u] == 0) {
        ++n;  // no return from where a surface in range would have given one
        continue;
      }
      const double z = row[u] / kf.depth_scale;
      const Vec3 pw = kf.T_w_c * (kf.camera.unproject(Vec2(u, v)) * z);
      if (has_floor() && pw.z() < floor_z_ + floor_cut(z)) continue;  // the floor it stands on
      ++n;
      const Vec3 q = pw - b.center;
      const double du = c * q.x() + sn * q.y(), dv = -sn * q.x() + c * q.y();
      if (std::abs(du) <= b.size.x() / 2 + grow && std::abs(dv) <= b.size.y() / 2 + grow &&
          std::abs(q.z()) <= b.size.z() / 2 + grow)
        ++support;
      else if (z < centre_depth - reach - grow)
        ++hidden;
    }
  }
  if (n < options_.min_absent_samples || hidden > options_.max_hidden_share * n)
    return Sighting::kUnknown;
  return support >= options_.min_support_share * n ? Sighting::kSeen : Sighting::kAbsent;
}

ObjectUpdateStats ObjectDatabase::update(const ObjectKeyframe& kf) {
  ObjectUpdateStats stats;
  if (!kf.depth || kf.depth->empty() || kf.depth->type != PixelType::kU16 ||
      kf.depth->width != kf.camera.width || kf.depth->height != kf.camera.height ||
      !(kf.depth_scale > 0.0))
    return stats;
  keyframe_poses_[kf.keyframe_id] = kf.T_w_c;
  update_floor(kf);

  // A static-class object caught moving leaves the database; it comes back where it stops.
  for (const detect::Detection& m : kf.moving_boxes) {
    for (auto it = entries_.begin(); it != entries_.end();) {
      PixelBox pb;
      if (confusable(it->second.object.label, m.label) &&
          project_box(it->second.object.box, kf.T_w_c, kf.camera, pb) &&
          iou(pb, to_box(m)) > options_.moving_iou) {
        it = entries_.erase(it);
        ++stats.removed_moving;
      } else {
        ++it;
      }
    }
  }

  stats.boxes = static_cast<int>(kf.static_boxes.size());
  std::unordered_set<int> measured;
  for (Measurement& m : measure_all(kf)) {
    ++stats.measured;
    // The object sharing most of the measurement's cells, else the nearest one close enough.
    Entry* match = nullptr;
    Entry* nearest = nullptr;
    double best_shared = options_.min_overlap, best_dist = 1e18;
    const auto cells = voxels_of(m.points_w);
    for (auto& [id, e] : entries_) {
      if (!confusable(e.object.label, m.label)) continue;
      const double shared = overlap(cells, e.voxels);
      if (shared >= best_shared) {
        best_shared = shared;
        match = &e;
      }
      const double dist = (e.object.box.center - m.box.center).head<2>().norm();
      if (same_object(e.object.box, m.box, options_.associate_factor) && dist < best_dist) {
        best_dist = dist;
        nearest = &e;
      }
    }
    if (!match) match = nearest;
    // Measurements walking away are followed from the last of them, not from where the object
    // stood: a push of 0.2 m a keyframe leaves the object's centre in two steps.
    const Vec2 at = m.box.center.head<2>();
    for (auto it = entries_.begin(); !match && it != entries_.end(); ++it) {
      Entry& e = it->second;
      if (confusable(e.object.label, m.label) && e.displaced > 0 &&
          (at - e.displaced_last).norm() <
              options_.associate_factor * std::max(typical_length(e.object), 0.3))
        match = &e;
    }
    // Only a view of the whole object says where it is: a part's centre walks with the
    // viewpoint (a stall's face in a table's box, a car cut by the image border).
    const bool whole_view = !m.cut && m.cut_towards.isZero();
    const MotionStep step =
        match && whole_view ? track_motion(*match, at, kf.stamp, stats) : MotionStep::kFuse;
    if (step == MotionStep::kHold) {
      measured.insert(match->object.id);
      match->held.push_back({{kf.keyframe_id, std::move(m.points_c), Vec3::Zero()},
                             m.score,
                             m.depth,
                             m.cut,
                             kf.stamp,
                             m.label});
      continue;
    }
    if (step == MotionStep::kRestart) {
      // A new place: what was seen of the object where it stood is no longer there.
      match->held.clear();
      match->views.clear();
      match->object.observations = match->object.whole_observations = 0;
      match->object.score_sum = 0.0;
      match->mean_depth = 0.0;
    }
    if (!match) {
      Entry e;
      e.object.id = next_id_++;
      e.object.label = m.label;
      e.object.first_seen = kf.stamp;
      match = &entries_.emplace(e.object.id, std::move(e)).first->second;
      ++stats.created;
    }
    measured.insert(match->object.id);
    const Vec3 cut_c = m.cut_towards.isZero()
                           ? Vec3::Zero()
                           : Vec3(kf.T_w_c.rotation().transpose() *
                                  Vec3(m.cut_towards.x(), m.cut_towards.y(), 0.0))
                                 .normalized();
    fuse(*match, {{kf.keyframe_id, std::move(m.points_c), cut_c},
                  m.score,
                  m.depth,
                  m.cut,
                  kf.stamp,
                  m.label});
    if (match->object.moving && static_cast<int>(match->views.size()) >= options_.still_views &&
        to_seconds(kf.stamp - match->still_since) >= options_.still_seconds) {
      match->object.moving = false;
      ++stats.stopped;
    }
  }
  // Where an object stood and the keyframe shows neither its box nor its surfaces, it is gone
  // (taken away, or pushed while out of view or between keyframes).
  for (auto it = entries_.begin(); it != entries_.end();) {
    Entry& e = it->second;
    // A moving object lost from view is somewhere else by now; it is found again where it stops.
    if (e.object.moving &&
        to_seconds(kf.stamp - e.object.last_seen) > options_.lost_mover_seconds) {
      it = entries_.erase(it);
      ++stats.lost_moving;
      continue;
    }
    const Sighting sighting = measured.count(e.object.id) ? Sighting::kSeen : look_for(e, kf);
    if (sighting == Sighting::kSeen) e.absent = 0;
    if (sighting == Sighting::kAbsent && ++e.absent >= options_.absent_keyframes) {
      it = entries_.erase(it);
      ++stats.removed_absent;
    } else {
      ++it;
    }
  }
  stats.merged = merge_duplicates();
  return stats;
}

void ObjectDatabase::reanchor(std::int64_t keyframe_id, const SE3& T_w_c) {
  auto it = keyframe_poses_.find(keyframe_id);
  if (it == keyframe_poses_.end()) return;
  it->second = T_w_c;
  for (auto& [id, e] : entries_) {
    const bool uses = std::any_of(e.views.begin(), e.views.end(), [&](const Observation& o) {
      return o.keyframe_id == keyframe_id;
    });
    if (uses) refit(e);
  }
}

std::vector<SemanticObject> ObjectDatabase::all_objects() const {
  std::vector<SemanticObject> out;
  for (const auto& [id, e] : entries_) out.push_back(e.object);
  return out;
}

std::vector<SemanticObject> ObjectDatabase::objects() const {
  std::vector<SemanticObject> out;
  for (const auto& [id, e] : entries_)
    if (!e.object.moving && e.object.observations >= options_.min_observations &&
        e.object.whole_observations >= options_.min_whole_observations)
      out.push_back(e.object);
  return out;
}

std::vector<io::SequenceObject> ObjectDatabase::to_sequence_objects() const {
  std::vector<io::SequenceObject> out;
  for (const SemanticObject& o : objects()) {
    io::SequenceObject s;
    s.id = o.id;
    s.label = o.label;
    s.center = o.box.center;
    s.size = o.box.size;
    s.yaw = o.box.yaw;
    s.observations = o.observations;
    s.first_seen = to_seconds(o.first_seen);
    s.last_seen = to_seconds(o.last_seen);
    out.push_back(s);
  }
  return out;
}

void ObjectDatabase::write_outputs(const std::string& dir) const {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error::at(dir, 0, "", "cannot create the output folder: " + ec.message());
  io::write_objects_json((std::filesystem::path(dir) / "objects.json").string(),
                         to_sequence_objects());
}

}  // namespace kestrel::semantic
