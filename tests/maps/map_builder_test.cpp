#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "maps/grid_io.hpp"
#include "maps/map_builder.hpp"
#include "maps/ply_writer.hpp"
#include "tests/maps/synthetic_depth.hpp"
#include "tests/test_paths.hpp"

using namespace kestrel;
using namespace kestrel::maps;

namespace {

MapKeyframe keyframe(const PinholeCamera& cam, const SE3& T, const Image& depth,
                     const std::vector<std::uint8_t>* mask = nullptr) {
  MapKeyframe kf;
  kf.T_w_c = T;
  kf.depth = &depth;
  kf.camera = cam;
  kf.depth_scale = 5000.0;
  kf.static_mask = mask;
  return kf;
}

int occupied_between(const OccupancyOctree& o, double x_min, double x_max) {
  int n = 0;
  for (const Vec3& p : o.occupied_voxels()) n += p.x() > x_min && p.x() < x_max;
  return n;
}

}  // namespace

TEST(MapBuilder, AWallBecomesOccupiedCellsAndTheSpaceBeforeItFree) {
  const PinholeCamera cam = test::small_camera();
  // Every pixel of this quarter-VGA camera: rays as dense as stride 4 at 640x480.
  MapBuilderOptions opt;
  opt.octree_stride = 1;
  opt.cloud_stride = 1;
  MapBuilder b(opt);
  const SE3 T = test::looking_along_x(Vec3(0, 0, 1.0));
  const Image d = test::wall_depth(cam, T, 3.0, {});
  EXPECT_GT(b.insert(keyframe(cam, T, d)), 10000u);
  const OccupancyGrid g = b.grid();
  ASSERT_FALSE(g.empty());
  // The wall: x in [3.0, 3.05) for |y| < 1.7 (the camera sees |y| < 1.83 at 3 m).
  int wall = 0, wall_seen = 0;
  for (double y = -1.7; y <= 1.7; y += 0.05) {
    const auto c = g.cell_of(Vec2(3.02, y));
    ASSERT_TRUE(c) << y;
    ++wall;
    wall_seen += g.at(*c) == kOccupied;
  }
  EXPECT_GE(wall_seen, wall - 1);
  // In front of it, inside the view cone: free, and nothing occupied anywhere else.
  const auto mid = g.cell_of(Vec2(2.0, 0.0));
  ASSERT_TRUE(mid);
  EXPECT_EQ(g.at(*mid), kFree);
  for (int y = 0; y < g.height(); ++y)
    for (int x = 0; x < g.width(); ++x) {
      const Vec2 p = g.center_of({x, y});
      if (g.at({x, y}) == kOccupied) {
        EXPECT_NEAR(p.x(), 3.025, 0.051) << p.transpose();
      }
    }
  // Behind the wall is unknown.
  const auto behind = g.cell_of(Vec2(3.2, 0.0));
  EXPECT_TRUE(!behind || g.at(*behind) == kUnknown);
}

// A sensor that ranges 13 m (a drone's, seen 11 m away at 45 degrees down): its calibration's
// range makes a wall 10 m away a surface of the map; the defaults (an 8 m sensor) only carve
// towards it, 8 m of free space and no wall.
TEST(MapBuilder, TheSensorsRangeDecidesHowFarSurfacesAreTrusted) {
  const MapBuilderOptions d = map_builder_options(std::nullopt);
  EXPECT_DOUBLE_EQ(d.max_depth, MapBuilderOptions{}.max_depth);
  EXPECT_DOUBLE_EQ(d.octree.max_range, MapBuilderOptions{}.octree.max_range);
  const MapBuilderOptions far = map_builder_options(13.0);
  EXPECT_DOUBLE_EQ(far.max_depth, 12.0);
  EXPECT_DOUBLE_EQ(far.octree.max_range, 13.0);

  const PinholeCamera cam = test::small_camera();
  const SE3 T = test::looking_along_x(Vec3(0, 0, 1.0));
  const Image depth = test::wall_depth(cam, T, 10.0, {});
  const auto wall_cells = [&](MapBuilderOptions o) {
    o.octree_stride = 1;  // every pixel of the quarter-VGA camera, as dense as stride 4 at VGA
    MapBuilder b(o);
    b.insert(keyframe(cam, T, depth));
    const OccupancyGrid g = b.grid();
    int n = 0;
    for (double y = -2.0; y <= 2.0; y += 0.1)
      if (const auto c = g.cell_of(Vec2(10.02, y)); c && g.at(*c) == kOccupied) ++n;
    const auto before = g.cell_of(Vec2(7.5, 0.0));
    return std::make_pair(n, before && g.at(*before) == kFree);
  };
  EXPECT_EQ(wall_cells(d).first, 0);
  const auto [ranged_wall, ranged_free_before] = wall_cells(far);
  EXPECT_GE(ranged_wall, 35);
  EXPECT_TRUE(ranged_free_before);
}

TEST(MapBuilder, AWalkerWhoLeftIsCarvedAway) {
  const PinholeCamera cam = test::small_camera();
  MapBuilderOptions opt;
  opt.octree_stride = 2;
  MapBuilder b(opt);
  test::Walker walker;
  walker.present = true;
  for (int k = 0; k < 15; ++k) {
    const SE3 T = test::looking_along_x(Vec3(0, 0.02 * k, 1.0));
    walker.present = k < 5;
    const Image d = test::wall_depth(cam, T, 3.0, walker);
    b.insert(keyframe(cam, T, d));
    if (k == 4) {
      EXPECT_GT(occupied_between(b.octree(), 1.3, 1.7), 50);
    }
  }
  EXPECT_EQ(occupied_between(b.octree(), 0.0, 2.9), 0);
  EXPECT_GT(occupied_between(b.octree(), 2.9, 3.1), 500);
  for (const CloudPoint& p : b.clean_cloud()) EXPECT_GT(p.p.x(), 2.9f);
}

TEST(MapBuilder, MaskedWalkerPixelsLeaveNoTrace) {
  const PinholeCamera cam = test::small_camera();
  MapBuilder b;
  test::Walker walker;
  walker.present = true;
  for (int k = 0; k < 3; ++k) {
    const SE3 T = test::looking_along_x(Vec3(0, 0.02 * k, 1.0));
    std::vector<std::uint8_t> walker_px;
    const Image d = test::wall_depth(cam, T, 3.0, walker, &walker_px);
    std::vector<std::uint8_t> mask(walker_px.size());
    for (std::size_t i = 0; i < mask.size(); ++i) mask[i] = walker_px[i] ? 0 : 1;
    b.insert(keyframe(cam, T, d, &mask));
  }
  EXPECT_EQ(occupied_between(b.octree(), 0.0, 2.9), 0);
  for (const CloudPoint& p : b.cloud().points()) EXPECT_GT(p.p.x(), 2.9f);
}

TEST(MapBuilder, StaticMaskFromBoxesBlanksTheGrownBoxes) {
  const auto m = static_mask_from_boxes(10, 8, {{2, 2, 4, 3}}, 1);
  int zeros = 0;
  for (auto v : m) zeros += v == 0;
  EXPECT_EQ(zeros, 4 * 3);
  EXPECT_EQ(m[1 * 10 + 1], 0);
  EXPECT_EQ(m[4 * 10 + 4], 1);
}

TEST(MapBuilder, WritesEveryOutputFile) {
  const PinholeCamera cam = test::small_camera();
  MapBuilder b;
  const SE3 T = test::looking_along_x(Vec3(0, 0, 1.0));
  const Image d = test::wall_depth(cam, T, 3.0, {});
  b.insert(keyframe(cam, T, d));
  const auto dir = test::temp_dir("maps-out") / "run";
  b.write_outputs(dir.string());
  for (const char* f : {"cloud.ply", "octomap.bt", "map.pgm", "map.yaml"})
    EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  EXPECT_EQ(read_ply((dir / "cloud.ply").string()).size(), b.clean_cloud().size());
  const OccupancyGrid g = read_map((dir / "map.yaml").string());
  EXPECT_EQ(g.cells(), b.grid().cells());
  const OccupancyOctree o = OccupancyOctree::read_binary((dir / "octomap.bt").string());
  EXPECT_EQ(o.occupied_voxels().size(), b.octree().occupied_voxels().size());
}

TEST(MapBuilder, NothingObservedWritesNoGridAndRemovesAStaleOne) {
  // A stereo run feeds no depth images: no cell is known. Earlier outputs in the same folder
  // must not pass for this run's.
  const PinholeCamera cam = test::small_camera();
  const auto dir = test::temp_dir("maps-empty") / "run";
  {
    MapBuilder b;
    const SE3 T = test::looking_along_x(Vec3(0, 0, 1.0));
    b.insert(keyframe(cam, T, test::wall_depth(cam, T, 3.0, {})));
    b.write_outputs(dir.string());
    ASSERT_TRUE(std::filesystem::exists(dir / "map.yaml"));
  }
  MapBuilder empty;
  ASSERT_EQ(empty.grid().width(), 0);
  empty.write_outputs(dir.string());
  EXPECT_FALSE(std::filesystem::exists(dir / "map.yaml"));
  EXPECT_FALSE(std::filesystem::exists(dir / "map.pgm"));
  EXPECT_TRUE(std::filesystem::exists(dir / "cloud.ply"));
  EXPECT_TRUE(std::filesystem::exists(dir / "octomap.bt"));
}

namespace {

// `d` with per-pixel Gaussian noise of sigma = a x depth^2 (the simulator's sensor model).
Image with_depth_noise(const Image& d, double a, unsigned seed) {
  Image out = d;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int v = 0; v < d.height; ++v) {
    auto* row = out.row<std::uint16_t>(v);
    for (int u = 0; u < d.width; ++u) {
      if (row[u] == 0) continue;
      const double z = row[u] / 5000.0;
      row[u] = static_cast<std::uint16_t>(std::lround((z + a * z * z * n(rng)) * 5000.0));
    }
  }
  return out;
}

// Depth of a horizontal plate (z = height, x in [x0, x1], |y| < 2) seen from T_w_c; 0 elsewhere.
Image plate_depth(const PinholeCamera& cam, const SE3& T_w_c, double height, double x0, double x1) {
  Image d = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);
  for (int v = 0; v < cam.height; ++v) {
    auto* row = d.row<std::uint16_t>(v);
    for (int u = 0; u < cam.width; ++u) {
      const Vec3 ray_w = T_w_c.rotation() * cam.unproject(Vec2(u, v));
      const Vec3 o = T_w_c.translation();
      row[u] = 0;
      if (ray_w.z() >= 0) continue;
      const double s = (height - o.z()) / ray_w.z();
      const Vec3 p = o + s * ray_w;
      if (p.x() >= x0 && p.x() <= x1 && std::abs(p.y()) < 2.0)
        row[u] = static_cast<std::uint16_t>(std::lround(s * 5000.0));
    }
  }
  return d;
}

}  // namespace

// A wall 6 m away read with the sensor's noise (sigma 11 cm there): raw readings scatter hits
// over voxels behind the wall that no ray reaches to carve; averaged over the neighbours on
// the same surface they stay in the wall's voxel.
TEST(MapBuilder, ANoisyFarWallStaysOneVoxelThick) {
  const PinholeCamera cam = test::small_camera();
  auto behind_wall = [&](int smooth_radius) {
    MapBuilderOptions opt;
    opt.octree_stride = 2;
    opt.smooth_radius = smooth_radius;
    MapBuilder b(opt);
    for (int k = 0; k < 6; ++k) {
      const SE3 T = test::looking_along_x(Vec3(0, 0.05 * k, 1.0));
      b.insert(keyframe(cam, T, with_depth_noise(test::wall_depth(cam, T, 6.0, {}), 0.003, k)));
    }
    EXPECT_GT(occupied_between(b.octree(), 5.9, 6.1), 100) << smooth_radius;
    return occupied_between(b.octree(), 6.15, 9.0);
  };
  EXPECT_GT(behind_wall(0), 100);
  EXPECT_LE(behind_wall(MapBuilderOptions{}.smooth_radius), 5);
}

// A table top seen from 2-5.7 m at 5-15 degrees: a ray that lands on it runs within a voxel of the
// top for metres, and carving all of it clears the top's voxels that other rays marked.
TEST(MapBuilder, ATableTopSeenAtAGrazingAngleStaysOccupied) {
  const PinholeCamera cam = test::small_camera();
  auto top_cells = [&](double max_margin) {
    MapBuilderOptions opt;
    opt.octree_stride = 2;
    opt.grazing_max_margin = max_margin;
    MapBuilder b(opt);
    for (int k = 0; k < 8; ++k) {
      // Looking along x and down 5 degrees, from 1.3 m, stepping back and sideways.
      const SE3 T0 = test::looking_along_x(Vec3(-0.1 * k, 0.03 * k, 1.3));
      const SE3 T(T0.so3() * SO3::exp(Vec3(-5.0 * M_PI / 180.0, 0, 0)), T0.translation());
      b.insert(keyframe(cam, T, plate_depth(cam, T, 0.75, 2.0, 5.0)));
    }
    const OccupancyGrid g = b.grid();
    int occupied = 0, cells = 0;
    for (double x = 2.55; x < 4.5; x += 0.1)
      for (double y = -0.45; y < 0.5; y += 0.1) {
        const auto c = g.cell_of(Vec2(x, y));
        if (!c) continue;
        ++cells;
        occupied += g.at(*c) == kOccupied;
      }
    EXPECT_GT(cells, 150);
    return static_cast<double>(occupied) / std::max(cells, 1);
  };
  EXPECT_LT(top_cells(0.0), 0.7);
  EXPECT_GE(top_cells(1.0), 0.9);
}

// Free space seen only through a gap low in the band (under a car's body) is not room for a
// robot: with a clearance the cell is free only where the band's lowest layers are all seen free.
TEST(OccupancyOctree, ProjectionNeedsTheClearanceSeenFree) {
  OccupancyOctree o;
  // Rays 0.15 m up (under the body) over x in [0, 4); rays 0.15-0.45 m up over x in [0, 2).
  std::vector<Eigen::Vector3f> low, high;
  for (double y = -0.5; y <= 0.5; y += 0.05) {
    low.emplace_back(4.0f, static_cast<float>(y), 0.15f);
    for (float z : {0.25f, 0.35f, 0.45f}) high.emplace_back(2.0f, static_cast<float>(y), z);
  }
  o.insert_free_rays(Vec3(0, 0, 0.15), low);
  for (const auto& e : high) o.insert_free_rays(Vec3(0, 0, e.z()), {e});
  const OccupancyGrid any = o.project(0.1, 1.6, 0.0), tall = o.project(0.1, 1.6, 0.4);
  const auto under = any.cell_of(Vec2(3.05, 0.05)), open = any.cell_of(Vec2(1.05, 0.05));
  ASSERT_TRUE(under && open);
  EXPECT_EQ(any.at(*under), kFree);
  EXPECT_EQ(any.at(*open), kFree);
  EXPECT_EQ(tall.at(*under), kUnknown);
  EXPECT_EQ(tall.at(*open), kFree);
}

TEST(MapBuilder, FreeCellsNoCameraCanReachBecomeUnknown) {
  // A free room (x, y in [0, 2)) and, beyond an occupied ring, a free pocket inside it.
  OccupancyGrid g(40, 40, 0.1, Vec2(0, 0), kFree);
  for (int y = 20; y <= 30; ++y)
    for (int x = 20; x <= 30; ++x)
      if (x == 20 || x == 30 || y == 20 || y == 30) g.set({x, y}, kOccupied);
  for (int x = 0; x < 40; ++x) g.set({x, 0}, kUnknown);  // under the camera: never seen
  OccupancyGrid h = g;
  mark_unreachable_unknown(h, {Vec2(0.05, 0.02)}, 1.0);
  EXPECT_EQ(h.at({5, 5}), kFree);
  EXPECT_EQ(h.at({35, 35}), kFree);
  EXPECT_EQ(h.at({20, 25}), kOccupied);
  EXPECT_EQ(h.at({25, 25}), kUnknown);
  EXPECT_EQ(h.at({21, 29}), kUnknown);
  // No free cell within the seed radius: nothing is reachable.
  OccupancyGrid far = g;
  mark_unreachable_unknown(far, {Vec2(-5.0, -5.0)}, 1.0);
  EXPECT_EQ(far.at({5, 5}), kUnknown);
}
