#include <gtest/gtest.h>

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
