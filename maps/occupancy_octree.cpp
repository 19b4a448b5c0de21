#include "maps/occupancy_octree.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>

#include "core/error.hpp"
#include "maps/free_space_rule.hpp"
#include "maps/octree_batch_update.hpp"
#include "maps/scan_cell_set.hpp"
#include "maps/voxel_key_index.hpp"

namespace kestrel::maps {

namespace {

std::uint64_t pack(const octomap::OcTreeKey& k) { return VoxelKeyIndex::pack(k[0], k[1], k[2]); }

}  // namespace

struct OccupancyOctree::Impl {
  explicit Impl(double res) : tree(res) {}
  octomap::OcTree tree;
  // One scan's cells, kept between scans so their tables are allocated once.
  ScanCellSet free_cells;
  VoxelKeyIndex occupied_cells, end_voxels;
  octomap::KeyRay ray;
  std::vector<CellUpdate> updates;

  ScanCellSet& reset_free_cells(const octomap::point3d& origin, double max_range) {
    octomap::OcTreeKey k;
    if (!tree.coordToKeyChecked(origin, k)) k = octomap::OcTreeKey(32768, 32768, 32768);
    // The rays end within max_range of the origin: a cube of that half-side holds them all.
    const int half = static_cast<int>(std::ceil(max_range / tree.getResolution())) + 2;
    free_cells.reset(pack(k), half);
    return free_cells;
  }
};

OccupancyOctree::OccupancyOctree(const OctreeOptions& options)
    : options_(options), impl_(std::make_unique<Impl>(options.resolution)) {
  auto& t = impl_->tree;
  t.setProbHit(options.prob_hit);
  t.setProbMiss(options.prob_miss);
  t.setClampingThresMin(options.clamp_min);
  t.setClampingThresMax(options.clamp_max);
}
OccupancyOctree::~OccupancyOctree() = default;

OccupancyOctree::OccupancyOctree(OccupancyOctree&&) noexcept = default;
OccupancyOctree& OccupancyOctree::operator=(OccupancyOctree&&) noexcept = default;

void OccupancyOctree::insert_scan(const Vec3& origin,
                                  const std::vector<Eigen::Vector3f>& points_w) {
  octomap::Pointcloud cloud;
  cloud.reserve(points_w.size());
  for (const auto& p : points_w) cloud.push_back(p.x(), p.y(), p.z());
  const octomap::point3d o(static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                           static_cast<float>(origin.z()));
  // discretize: one ray per end voxel, which is what keeps a keyframe under a few ms.
  impl_->tree.insertPointCloud(cloud, o, options_.max_range, /*lazy_eval=*/false,
                               /*discretize=*/true);
}

void OccupancyOctree::insert_scan(const Vec3& origin, const std::vector<Eigen::Vector3f>& points_w,
                                  const std::vector<Eigen::Vector3f>& carve_ends_w) {
  if (carve_ends_w.size() != points_w.size()) return insert_scan(origin, points_w);
  auto& t = impl_->tree;
  const octomap::point3d o(static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                           static_cast<float>(origin.z()));
  ScanCellSet& free_cells = impl_->reset_free_cells(o, options_.max_range);
  VoxelKeyIndex& occupied_cells = impl_->occupied_cells;
  VoxelKeyIndex& end_voxels = impl_->end_voxels;
  occupied_cells.clear();
  end_voxels.clear();
  octomap::KeyRay& ray = impl_->ray;
  const auto max_range = static_cast<float>(options_.max_range);
  for (std::size_t i = 0; i < points_w.size(); ++i) {
    const octomap::point3d p(points_w[i].x(), points_w[i].y(), points_w[i].z());
    octomap::point3d end(carve_ends_w[i].x(), carve_ends_w[i].y(), carve_ends_w[i].z());
    // One ray per end voxel (as insertPointCloud's discretize): rays ending in one voxel
    // carve nearly the same cells, and casting each would double a keyframe's time.
    octomap::OcTreeKey k;
    if (!t.coordToKeyChecked(p, k)) continue;
    if ((p - o).norm() <= max_range && !occupied_cells.insert(pack(k)).second) continue;
    if (!end_voxels.insert(pack(k)).second) continue;
    const octomap::point3d d = end - o;
    if (d.norm() > max_range) end = o + d * (max_range / d.norm());
    if (t.computeRayKeys(o, end, ray))
      for (const auto& rk : ray) free_cells.insert(pack(rk));
  }
  std::vector<CellUpdate>& updates = impl_->updates;
  updates.clear();
  for (std::size_t i = 0; i < free_cells.size(); ++i)
    if (!occupied_cells.contains(free_cells.key(i))) updates.push_back({free_cells.key(i), false});
  for (std::size_t i = 0; i < occupied_cells.size(); ++i)
    updates.push_back({occupied_cells.key(i), true});
  apply_cell_updates(t, updates);
}

void OccupancyOctree::insert_free_rays(const Vec3& origin,
                                       const std::vector<Eigen::Vector3f>& ends_w) {
  auto& t = impl_->tree;
  const octomap::point3d o(static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                           static_cast<float>(origin.z()));
  ScanCellSet& free_cells = impl_->reset_free_cells(o, options_.max_range);
  octomap::KeyRay& ray = impl_->ray;
  for (const auto& e : ends_w) {
    octomap::point3d end(e.x(), e.y(), e.z());
    const octomap::point3d d = end - o;
    if (d.norm() > options_.max_range)
      end = o + d * static_cast<float>(options_.max_range / d.norm());
    if (t.computeRayKeys(o, end, ray))
      for (const auto& rk : ray) free_cells.insert(pack(rk));
  }
  std::vector<CellUpdate>& updates = impl_->updates;
  updates.clear();
  for (std::size_t i = 0; i < free_cells.size(); ++i) updates.push_back({free_cells.key(i), false});
  apply_cell_updates(t, updates);
}

bool OccupancyOctree::is_occupied(const Vec3& p) const {
  const auto* n = impl_->tree.search(p.x(), p.y(), p.z());
  return n && impl_->tree.isNodeOccupied(n);
}

bool OccupancyOctree::is_known(const Vec3& p) const {
  return impl_->tree.search(p.x(), p.y(), p.z()) != nullptr;
}

std::vector<Vec3> OccupancyOctree::occupied_voxels() const {
  std::vector<Vec3> out;
  const auto& t = impl_->tree;
  const double res = t.getResolution();
  for (auto it = t.begin_leafs(), end = t.end_leafs(); it != end; ++it) {
    if (!t.isNodeOccupied(*it)) continue;
    const double size = it.getSize();
    const octomap::point3d c = it.getCoordinate();
    const int n = std::max(1, static_cast<int>(std::lround(size / res)));
    const Vec3 corner(c.x() - size / 2, c.y() - size / 2, c.z() - size / 2);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        for (int k = 0; k < n; ++k)
          out.push_back(corner + Vec3((i + 0.5) * res, (j + 0.5) * res, (k + 0.5) * res));
  }
  return out;
}

std::size_t OccupancyOctree::leaf_count() const { return impl_->tree.getNumLeafNodes(); }

BandColumns OccupancyOctree::project_columns(double z_min, double z_max,
                                             double free_clearance) const {
  const auto& t = impl_->tree;
  const double res = t.getResolution();
  BandColumns cols;
  cols.layer_height = res;
  double x0, y0, z0, x1, y1, z1;
  t.getMetricMin(x0, y0, z0);
  t.getMetricMax(x1, y1, z1);
  if (t.size() == 0 || !(x1 > x0) || !(y1 > y0)) return cols;
  // Snap the origin to the voxel lattice so grid cells and voxel columns coincide.
  const double ox = std::floor(x0 / res + 1e-6) * res;
  const double oy = std::floor(y0 / res + 1e-6) * res;
  const int w = static_cast<int>(std::ceil((x1 - ox) / res - 1e-6));
  const int h = static_cast<int>(std::ceil((y1 - oy) / res - 1e-6));
  cols.grid = OccupancyGrid(w, h, res, Vec2(ox, oy), kUnknown);
  OccupancyGrid& grid = cols.grid;
  // Per cell, which voxel layers of the band's lowest free_clearance metres are seen free.
  cols.layers = std::clamp(static_cast<int>(std::ceil(free_clearance / res - 1e-6)), 0, 31);
  cols.layer_base = std::floor(z_min / res + 0.5) * res;
  const int layers = cols.layers;
  if (layers > 0) cols.free_layers.assign(grid.cells().size(), 0);
  for (auto it = t.begin_leafs(), end = t.end_leafs(); it != end; ++it) {
    const double size = it.getSize();
    const octomap::point3d c = it.getCoordinate();
    // Float voxel bounds sit on the band limits (a floor voxel ends at 0.1 m): compare with
    // slack so that a voxel counts only when it reaches well into the band.
    const double eps = 0.25 * res;
    if (c.z() + size / 2 <= z_min + eps || c.z() - size / 2 >= z_max - eps) continue;
    const bool occ = t.isNodeOccupied(*it);
    const int n = std::max(1, static_cast<int>(std::lround(size / res)));
    const int cx0 = static_cast<int>(std::floor((c.x() - size / 2 - ox) / res + 0.5));
    const int cy0 = static_cast<int>(std::floor((c.y() - size / 2 - oy) / res + 0.5));
    // The voxel's layers from the band's base, clipped to the clearance.
    const int l0 = static_cast<int>(std::floor((c.z() - size / 2 - cols.layer_base) / res + 0.5));
    std::uint32_t bits = 0;
    if (!occ)
      for (int l = std::max(0, l0); l < std::min(layers, l0 + n); ++l)
        bits |= std::uint32_t{1} << l;
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const GridCell cell{cx0 + i, cy0 + j};
        if (!grid.contains(cell)) continue;
        if (occ) {
          grid.set(cell, kOccupied);
          continue;
        }
        if (grid.at(cell) == kUnknown) grid.set(cell, kFree);
        if (bits) cols.free_layers[grid.index(cell)] |= bits;
      }
    }
  }
  return cols;
}

OccupancyGrid OccupancyOctree::project(double z_min, double z_max, double free_clearance) const {
  return resolve_columns(project_columns(z_min, z_max, free_clearance), nullptr);
}

void OccupancyOctree::write_binary(const std::string& path) const {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error::at(path, 0, "", "cannot write the OctoMap");
  if (!impl_->tree.writeBinaryConst(out) || !out) throw Error::at(path, 0, "", "write failed");
}

OccupancyOctree OccupancyOctree::read_binary(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open the OctoMap");
  // readBinary needs the tree's resolution from the header; it sets it itself.
  OccupancyOctree o;
  if (!o.impl_->tree.readBinary(in)) throw Error::at(path, 0, "", "not a binary OctoMap (.bt)");
  o.options_.resolution = o.impl_->tree.getResolution();
  return o;
}

}  // namespace kestrel::maps
