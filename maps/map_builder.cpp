#include "maps/map_builder.hpp"

#include <algorithm>
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

  std::vector<Eigen::Vector3f> hits, far_rays;
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
      const float z = drow[u] * inv_scale;
      if (drow[u] == 0 || z < zmin) continue;
      const Eigen::Vector3f pw = R * (rays[i].cast<float>() * z) + t;
      if (z > zmax) {
        // Too far to trust as a surface, still evidence that the space well in front of it is
        // empty (stopped short by the noise this depth has).
        if (for_octo) far_rays.push_back(R * (rays[i].cast<float>() * (z - far_margin)) + t);
        continue;
      }
      if (for_octo) hits.push_back(pw);
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
  if (!far_rays.empty()) octree_.insert_free_rays(origin, far_rays);
  octree_.insert_scan(origin, hits);
  return hits.size();
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
  return octree_.project(options_.grid_z_min, options_.grid_z_max);
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
