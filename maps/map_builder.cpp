#include "maps/map_builder.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

#include "core/error.hpp"
#include "maps/grid_io.hpp"
#include "maps/ply_writer.hpp"

namespace kestrel::maps {
namespace {

bool same_camera(const PinholeCamera& a, const PinholeCamera& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy &&
         a.cx == b.cx && a.cy == b.cy && a.model == b.model && a.dist == b.dist;
}

}  // namespace

double smoothed_depth(const Image& depth, int u, int v, int radius, double noise_z2,
                      double depth_scale) {
  const std::uint16_t centre = depth.row<std::uint16_t>(v)[u];
  if (centre == 0 || radius <= 0) return centre;
  const double z0 = centre / depth_scale;
  const double tol = (2.5 * noise_z2 * z0 * z0 + 0.02) * depth_scale;
  // Two passes: the neighbours near the centre's reading, then those near their mean. One pass
  // keeps much of an outlying centre's error (its window is centred on the outlier).
  double ref = centre;
  for (int pass = 0; pass < 2; ++pass) {
    double sum = 0.0;
    int n = 0;
    for (int y = std::max(0, v - radius); y <= std::min(depth.height - 1, v + radius); ++y) {
      const auto* row = depth.row<std::uint16_t>(y);
      for (int x = std::max(0, u - radius); x <= std::min(depth.width - 1, u + radius); ++x) {
        if (row[x] == 0 || std::abs(static_cast<double>(row[x]) - ref) > tol) continue;
        sum += row[x];
        ++n;
      }
    }
    if (n == 0) break;  // the second pass lost every reading: keep the first mean
    ref = sum / n;
  }
  return ref;
}

void mark_unreachable_unknown(OccupancyGrid& g, const std::vector<Vec2>& seeds_xy,
                              double seed_radius) {
  const int w = g.width(), h = g.height();
  const std::vector<int> region = free_regions(g);
  std::vector<std::uint8_t> reached;  // per region
  const int r = static_cast<int>(std::ceil(seed_radius / g.resolution()));
  for (const Vec2& xy : seeds_xy) {
    // The nearest free cell within the radius (the cells under a camera are rarely seen).
    const double fx = (xy.x() - g.origin().x()) / g.resolution();
    const double fy = (xy.y() - g.origin().y()) / g.resolution();
    if (!std::isfinite(fx) || !std::isfinite(fy)) continue;
    const int cx = static_cast<int>(std::floor(fx)), cy = static_cast<int>(std::floor(fy));
    double best = 1e18;
    GridCell seed{-1, -1};
    for (int y = std::max(0, cy - r); y <= std::min(h - 1, cy + r); ++y)
      for (int x = std::max(0, cx - r); x <= std::min(w - 1, cx + r); ++x) {
        const double d2 = double(x - cx) * (x - cx) + double(y - cy) * (y - cy);
        if (d2 <= double(r) * r && d2 < best && g.at({x, y}) == kFree) {
          best = d2;
          seed = {x, y};
        }
      }
    if (seed.x < 0) continue;
    const auto label = static_cast<std::size_t>(region[g.index(seed)]);
    if (label >= reached.size()) reached.resize(label + 1, 0);
    reached[label] = 1;
  }
  for (std::size_t i = 0; i < g.cells().size(); ++i) {
    if (g.cells()[i] != kFree) continue;
    const auto label = static_cast<std::size_t>(region[i]);
    if (label >= reached.size() || !reached[label]) g.cells()[i] = kUnknown;
  }
}

std::vector<std::uint8_t> static_mask_from_boxes(int width, int height,
                                                 const std::vector<MapBoxRegion>& boxes,
                                                 int margin) {
  std::vector<std::uint8_t> mask(
      static_cast<std::size_t>(std::max(0, width)) * static_cast<std::size_t>(std::max(0, height)),
      1);
  for (const MapBoxRegion& b : boxes) {
    const int x0 = std::clamp(b.x_min - margin, 0, width),
              x1 = std::clamp(b.x_max + margin, 0, width);
    const int y0 = std::clamp(b.y_min - margin, 0, height),
              y1 = std::clamp(b.y_max + margin, 0, height);
    for (int y = y0; y < y1; ++y)
      std::fill(mask.begin() + static_cast<std::ptrdiff_t>(y) * width + x0,
                mask.begin() + static_cast<std::ptrdiff_t>(y) * width + x1, 0);
  }
  return mask;
}

MapBuilder::MapBuilder(const MapBuilderOptions& options)
    : options_(options), octree_(options.octree), cloud_(options.cloud_voxel) {}

const std::vector<Vec3>& MapBuilder::rays_for(const PinholeCamera& camera) {
  if (rays_.empty() || !same_camera(camera, ray_camera_)) {
    ray_camera_ = camera;
    rays_.resize(static_cast<std::size_t>(camera.width) * camera.height);
    for (int v = 0; v < camera.height; ++v)
      for (int u = 0; u < camera.width; ++u)
        rays_[static_cast<std::size_t>(v) * camera.width + u] = camera.unproject(Vec2(u, v));
  }
  return rays_;
}

MapBuilderOptions map_builder_options(std::optional<double> depth_max) {
  MapBuilderOptions o;
  if (depth_max && *depth_max > 1.0) {
    o.max_depth = *depth_max - 1.0;
    o.octree.max_range = *depth_max;
  }
  return o;
}

std::size_t MapBuilder::insert(const MapKeyframe& kf) {
  if (!kf.depth || kf.depth->empty() || kf.depth->type != PixelType::kU16 ||
      kf.depth->channels != 1 || kf.depth->width != kf.camera.width ||
      kf.depth->height != kf.camera.height || !(kf.depth_scale > 0.0))
    return 0;  // nothing usable; the caller's status, not an exception (DESIGN.md)
  const int w = kf.camera.width, h = kf.camera.height;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  const bool has_color = kf.color && !kf.color->empty() && kf.color->width == w &&
                         kf.color->height == h && kf.color->type == PixelType::kU8;
  const bool has_mask = kf.static_mask && kf.static_mask->size() == n;
  const bool has_labels = kf.labels && kf.labels->size() == n;
  const std::vector<Vec3>& rays = rays_for(kf.camera);
  const Eigen::Matrix3f R = kf.T_w_c.rotation().cast<float>();
  const Eigen::Vector3f t = kf.T_w_c.translation().cast<float>();
  const float inv_scale = static_cast<float>(1.0 / kf.depth_scale);
  const float zmin = static_cast<float>(options_.min_depth);
  const float zmax = static_cast<float>(options_.max_depth);
  const float far_margin = static_cast<float>(options_.far_ray_margin);

  std::vector<Eigen::Vector3f> hits, carve_ends, far_rays;
  hits.reserve(n / (options_.octree_stride * options_.octree_stride) + 1);
  const int cs = std::max(1, options_.cloud_stride);
  const int os = std::max(1, options_.octree_stride);
  const int step = std::gcd(cs, os);
  for (int v = 0; v < h; v += step) {
    const auto* drow = kf.depth->row<std::uint16_t>(v);
    const bool cloud_row = v % cs == 0, octo_row = v % os == 0;
    for (int u = 0; u < w; u += step) {
      const bool for_cloud = cloud_row && u % cs == 0;
      const bool for_octo = octo_row && u % os == 0;
      if (!for_cloud && !for_octo) continue;
      const std::size_t i = static_cast<std::size_t>(v) * w + u;
      if (has_mask && (*kf.static_mask)[i] == 0) continue;
      if (drow[u] == 0) continue;
      const float z = static_cast<float>(smoothed_depth(*kf.depth, u, v, options_.smooth_radius,
                                                        options_.depth_noise_z2, kf.depth_scale) *
                                         inv_scale);
      if (z < zmin) continue;
      const Eigen::Vector3f pw = R * (rays[i].cast<float>() * z) + t;
      if (z > zmax) {
        // Too far to trust as a surface, still evidence that the space well in front of it is
        // empty (stopped short by the noise this depth has).
        if (for_octo) far_rays.push_back(R * (rays[i].cast<float>() * (z - far_margin)) + t);
        continue;
      }
      if (for_octo) {
        hits.push_back(pw);
        carve_ends.push_back(carve_end(kf, u, v, z, pw, t));
      }
      if (for_cloud) {
        std::uint8_t r = 200, g = 200, b = 200;
        if (has_color) {
          const std::uint8_t* px = kf.color->row<std::uint8_t>(v) + u * kf.color->channels;
          if (kf.color->channels >= 3) {
            b = px[0];
            g = px[1];
            r = px[2];
          } else {
            r = g = b = px[0];
          }
        }
        cloud_.add(pw, r, g, b, has_labels ? (*kf.labels)[i] : std::uint16_t{0});
      }
    }
  }
  const Vec3 origin = kf.T_w_c.translation();
  camera_xy_.push_back(origin.head<2>());
  views_.push_back(frustum_of(kf.T_w_c, kf.camera, options_.min_depth, options_.octree.max_range));
  if (kf.footprint && kf.footprint->radius > 0.0) footprints_.push_back(*kf.footprint);
  if (!far_rays.empty()) octree_.insert_free_rays(origin, far_rays);
  octree_.insert_scan(origin, hits, carve_ends);
  return hits.size();
}

Eigen::Vector3f MapBuilder::carve_end(const MapKeyframe& kf, int u, int v, float z,
                                      const Eigen::Vector3f& p_w,
                                      const Eigen::Vector3f& o_w) const {
  const double margin_max = options_.grazing_max_margin;
  const double clearance = options_.grazing_clearance * options_.octree.resolution;
  if (!(margin_max > 0.0) || !(clearance > 0.0)) return p_w;
  // The surface's normal from the readings a few pixels around (u, v), when they lie on the
  // same surface; else the full clearance along the ray (an edge: no surface to keep).
  const int k = std::max(1, options_.octree_stride / 2);
  const int w = kf.camera.width, h = kf.camera.height;
  if (u - k < 0 || v - k < 0 || u + k >= w || v + k >= h) return p_w;
  const double scale = kf.depth_scale;
  // Same surface: within the noise plus what a surface at up to 84 degrees (tan 10) adds.
  const double tol =
      (3.0 * options_.depth_noise_z2 * z * z + 0.02 + 10.0 * z * k / kf.camera.fx) * scale;
  Vec3 q[4];
  const int du[4] = {-k, k, 0, 0}, dv[4] = {0, 0, -k, k};
  for (int i = 0; i < 4; ++i) {
    const std::uint16_t raw = kf.depth->row<std::uint16_t>(v + dv[i])[u + du[i]];
    if (raw == 0 || std::abs(raw - z * scale) > tol) return p_w;
    const double zi = smoothed_depth(*kf.depth, u + du[i], v + dv[i], options_.smooth_radius,
                                     options_.depth_noise_z2, scale) /
                      scale;
    q[i] = kf.camera.unproject(Vec2(u + du[i], v + dv[i])) * zi;
  }
  const Vec3 n = (q[1] - q[0]).cross(q[3] - q[2]);
  const Vec3 ray = kf.camera.unproject(Vec2(u, v));
  if (!(n.norm() > 0.0)) return p_w;
  const double cos_incidence = std::abs(n.dot(ray)) / (n.norm() * ray.norm());
  const double margin = std::min(margin_max, clearance / std::max(cos_incidence, 1e-3));
  const Eigen::Vector3f d = p_w - o_w;
  const float len = d.norm();
  if (!(len > 0.0f)) return p_w;
  return o_w + d * std::max(0.0f, 1.0f - static_cast<float>(margin) / len);
}

std::vector<CloudPoint> MapBuilder::clean_cloud() const {
  std::vector<CloudPoint> pts = cloud_.points();
  std::erase_if(pts, [&](const CloudPoint& c) {
    const Vec3 p = c.p.cast<double>();
    return octree_.is_known(p) && !octree_.is_occupied(p);
  });
  return pts;
}

OccupancyGrid MapBuilder::grid() const {
  const BandColumns cols = octree_.project_columns(options_.grid_z_min, options_.grid_z_max,
                                                   options_.grid_free_clearance);
  std::vector<std::uint32_t> excused;
  if (options_.clearance_spares_unobservable) excused = unobservable_layers(cols, views_);
  OccupancyGrid g = resolve_columns(cols, excused.empty() ? nullptr : &excused);
  if (g.empty()) return g;
  // Reachability on what the cameras saw; the footprints after it: they are free because the
  // robot stood there, whether or not its view joins them (a camera whose band starts above it
  // sees no band voxel within ~0.5 m), and a footprint must not become the seed nearest a
  // camera in place of the cells it saw.
  if (options_.reachable_seed_radius > 0.0)
    mark_unreachable_unknown(g, camera_xy_, options_.reachable_seed_radius);
  if (!footprints_.empty()) g = clear_footprints(g, footprints_);
  return g;
}

void MapBuilder::write_outputs(const std::string& dir) const {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error::at(dir, 0, "", "cannot create the output folder: " + ec.message());
  const std::filesystem::path d(dir);
  write_ply((d / "cloud.ply").string(), clean_cloud());
  octree_.write_binary((d / "octomap.bt").string());
  // No dense input (a stereo or monocular run) leaves no cell: a 0x0 image is no map a
  // map_server, our reader or the report can load, so there is no grid to write. A stale
  // grid from an earlier run in the same folder must not pass for this one's.
  const OccupancyGrid g = grid();
  if (g.width() == 0 || g.height() == 0) {
    std::filesystem::remove(d / "map.yaml", ec);
    std::filesystem::remove(d / "map.pgm", ec);
    return;
  }
  write_map((d / "map.yaml").string(), g);
}

}  // namespace kestrel::maps
