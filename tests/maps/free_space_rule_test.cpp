#include "maps/free_space_rule.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "maps/map_builder.hpp"
#include "tests/maps/synthetic_depth.hpp"

using namespace kestrel;
using namespace kestrel::maps;

namespace {

// A camera 0.4 m above the floor (a ground robot's) at the world origin, looking along +x.
SE3 low_camera(double x = 0.0) { return test::looking_along_x(Vec3(x, 0.0, 0.4)); }

// The ugv-loop scene in small: floor z = 0, a wall x = 6 and a parked car's body (a box over
// x in [3.05, 4.5], |y| < 0.9, z in [0.3, 1.5]) standing on wheels the rays pass between.
Image car_scene_depth(const PinholeCamera& cam, const SE3& T_w_c) {
  Image d = Image::allocate(cam.width, cam.height, 1, PixelType::kU16);
  const Vec3 o = T_w_c.translation();
  const Vec3 lo(3.05, -0.9, 0.3), hi(4.5, 0.9, 1.5);
  for (int v = 0; v < cam.height; ++v) {
    auto* row = d.row<std::uint16_t>(v);
    for (int u = 0; u < cam.width; ++u) {
      const Vec3 r = T_w_c.rotation() * cam.unproject(Vec2(u, v));  // camera z = 1
      double s = std::numeric_limits<double>::infinity();
      if (r.z() < 0) s = std::min(s, -o.z() / r.z());
      if (r.x() > 0) s = std::min(s, (6.0 - o.x()) / r.x());
      double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        if (std::abs(r[k]) < 1e-12) {
          if (o[k] < lo[k] || o[k] > hi[k]) t0 = t1 + 1;
          continue;
        }
        double a = (lo[k] - o[k]) / r[k], b = (hi[k] - o[k]) / r[k];
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a);
        t1 = std::min(t1, b);
      }
      if (t0 <= t1) s = std::min(s, t0);
      row[u] = std::isfinite(s) ? static_cast<std::uint16_t>(std::lround(s * 5000.0)) : 0;
    }
  }
  return d;
}

MapKeyframe keyframe(const PinholeCamera& cam, const SE3& T, const Image& depth) {
  MapKeyframe kf;
  kf.T_w_c = T;
  kf.depth = &depth;
  kf.camera = cam;
  kf.depth_scale = 5000.0;
  return kf;
}

std::int8_t cell_at(const OccupancyGrid& g, double x, double y) {
  const auto c = g.cell_of(Vec2(x, y));
  return c ? g.at(*c) : std::int8_t{-2};  // -2: outside the grid
}

}  // namespace

TEST(FreeSpaceRule, TheFrustumHoldsWhatTheCameraCouldSee) {
  const PinholeCamera cam = test::small_camera();  // 160x120, +-31 x +-24.6 degrees
  const ViewFrustum v = frustum_of(low_camera(), cam, 0.3, 8.0);
  EXPECT_TRUE(in_frustum(v, Vec3(2.0, 0.0, 0.4)));
  EXPECT_TRUE(in_frustum(v, Vec3(2.0, 1.0, 0.15)));
  EXPECT_FALSE(in_frustum(v, Vec3(-2.0, 0.0, 0.4)));  // behind
  EXPECT_FALSE(in_frustum(v, Vec3(2.0, 2.0, 0.4)));   // right of the field of view
  // The floor band right in front: 0.25 m below the camera is out of view nearer than 0.54 m.
  EXPECT_FALSE(in_frustum(v, Vec3(0.45, 0.0, 0.15)));
  EXPECT_TRUE(in_frustum(v, Vec3(0.65, 0.0, 0.15)));
  EXPECT_FALSE(in_frustum(v, Vec3(0.2, 0.0, 0.4)));  // nearer than the sensor's minimum depth
  EXPECT_EQ(visibility(v, Vec3(0.2, 0.0, 0.4)), Visibility::kBlindZone);
  EXPECT_EQ(visibility(v, Vec3(0.45, 0.0, 0.15)), Visibility::kBlindZone);
  EXPECT_EQ(visibility(v, Vec3(0.45, 0.5, 0.15)), Visibility::kOutside);  // beside it too
  EXPECT_EQ(visibility(v, Vec3(2.0, 0.0, 0.4)), Visibility::kInView);
  EXPECT_FALSE(in_frustum(v, Vec3(8.5, 0.0, 0.4)));  // beyond the carving range
}

TEST(FreeSpaceRule, OnlyLayersNoViewHadAreExcused) {
  BandColumns c;
  c.grid = OccupancyGrid(20, 1, 0.1, Vec2(0.0, -0.05), kFree);
  c.layers = 4;  // z 0.1 .. 0.5
  c.layer_base = 0.1;
  c.layer_height = 0.1;
  c.free_layers.assign(20, 0b1110);  // the lowest layer never seen free
  c.grid.set({15, 0}, kOccupied);
  c.grid.set({16, 0}, kUnknown);
  const PinholeCamera cam = test::small_camera();
  const std::vector<ViewFrustum> views = {frustum_of(low_camera(), cam, 0.3, 8.0)};
  const std::vector<std::uint32_t> ex = unobservable_layers(c, views);
  // x = 0.45: layer 0 (mid-height 0.15 m) is below the field of view; x = 1.05: in it.
  EXPECT_EQ(ex[4], 0b0001u);
  EXPECT_EQ(ex[10], 0u);
  EXPECT_EQ(ex[15], 0u);  // not band-free: not examined
  EXPECT_EQ(ex[16], 0u);
  const OccupancyGrid strict = resolve_columns(c, nullptr), spared = resolve_columns(c, &ex);
  EXPECT_EQ(strict.at({4, 0}), kUnknown);
  EXPECT_EQ(spared.at({4, 0}), kFree);
  EXPECT_EQ(spared.at({10, 0}), kUnknown);  // in view, not seen free: maybe under something
  EXPECT_EQ(spared.at({15, 0}), kOccupied);
  EXPECT_EQ(spared.at({16, 0}), kUnknown);
  // No view at all excuses nothing; nor does a view that has the column beside it (the
  // camera turned 90 degrees left: x = 0.45 lies beside its field of view).
  EXPECT_EQ(unobservable_layers(c, {})[4], 0u);
  Mat3 R;
  R << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // camera x, y, z along world +x, -z, +y
  const std::vector<ViewFrustum> beside = {
      frustum_of(SE3(SO3(R), Vec3(0.0, 0.0, 0.4)), cam, 0.3, 8.0)};
  EXPECT_EQ(visibility(beside[0], Vec3(0.45, 0.0, 0.15)), Visibility::kOutside);
  EXPECT_EQ(unobservable_layers(c, beside)[4], 0u);
  // No clearance asks for no layer.
  BandColumns any = c;
  any.layers = 0;
  any.free_layers.clear();
  EXPECT_EQ(resolve_columns(any, nullptr).at({10, 0}), kFree);
}

TEST(FreeSpaceRule, FootprintClearingFreesTheDiscAndGrowsTheGrid) {
  OccupancyGrid g(10, 10, 0.1, Vec2(0.0, 0.0), kUnknown);
  g.set({2, 2}, kOccupied);
  g.set({8, 8}, kFree);
  const OccupancyGrid out = clear_footprints(g, {{Vec2(0.25, 0.25), 0.2}, {Vec2(-0.5, 0.5), 0.2}});
  // The second disc lies left of the grid: it grows, keeping the old cells where they were.
  EXPECT_LE(out.origin().x(), -0.7 + 1e-9);
  EXPECT_NEAR(std::remainder(out.origin().x() / 0.1, 1.0), 0.0, 1e-9);  // same lattice
  EXPECT_EQ(out.resolution(), 0.1);
  EXPECT_EQ(cell_at(out, 0.25, 0.25), kOccupied);  // evidence of an obstacle is kept
  EXPECT_EQ(cell_at(out, 0.35, 0.25), kFree);
  EXPECT_EQ(cell_at(out, 0.15, 0.35), kFree);
  EXPECT_EQ(cell_at(out, 0.55, 0.25), kUnknown);  // beyond the radius
  EXPECT_EQ(cell_at(out, 0.85, 0.85), kFree);
  EXPECT_EQ(cell_at(out, -0.45, 0.45), kFree);
  EXPECT_EQ(cell_at(out, -0.75, 0.45), kUnknown);
  int free = 0;
  for (std::int8_t v : out.cells()) free += v == kFree;
  EXPECT_GE(free, 1 + 8 + 9);  // 13-cell discs, less the occupied centre of the first
  EXPECT_LE(free, 1 + 12 + 13);
  // An empty grid becomes the disc alone; nothing to clear leaves the grid as it was.
  const OccupancyGrid only = clear_footprints(OccupancyGrid(), {{Vec2(3.0, 4.0), 0.3}}, 0.05);
  EXPECT_EQ(only.resolution(), 0.05);
  EXPECT_EQ(cell_at(only, 3.0, 4.0), kFree);
  EXPECT_EQ(clear_footprints(g, {}).cells(), g.cells());
  // Where the robot stands now, even an occupied cell is free.
  const OccupancyGrid now = clear_footprints(g, {{Vec2(0.25, 0.25), 0.2}}, 0.1, true);
  EXPECT_EQ(cell_at(now, 0.25, 0.25), kFree);
  EXPECT_EQ(cell_at(now, 0.85, 0.85), kFree);
  EXPECT_EQ(cell_at(now, 0.55, 0.25), kUnknown);
}

// The whole rule on a rendered scene: a camera 0.4 m up before a parked car. The space under
// the car's body stays unknown; the floor band right in front of the camera, which it cannot
// see, is free by what it sees above it; the robot's own disc is free by footprint.
TEST(FreeSpaceRule, ALowCameraKeepsItsSurroundingsFreeAndTheSpaceUnderACarUnknown) {
  const PinholeCamera cam = test::small_camera();
  const SE3 T = low_camera();
  const Image d = car_scene_depth(cam, T);
  auto build = [&](double clearance, bool spare, bool footprint) {
    MapBuilderOptions o;
    o.octree_stride = 1;
    o.cloud_stride = 1;
    o.grid_free_clearance = clearance;
    o.clearance_spares_unobservable = spare;
    MapBuilder b(o);
    MapKeyframe kf = keyframe(cam, T, d);
    if (footprint) kf.footprint = Footprint{Vec2(-0.15, 0.0), 0.25};
    b.insert(kf);
    return b.grid();
  };
  const OccupancyGrid off = build(0.0, false, false), strict = build(0.4, false, false),
                      rule = build(0.4, true, false), robot = build(0.4, true, true);
  // Under the body: seen free low down only.
  EXPECT_EQ(cell_at(off, 3.75, 0.05), kFree);
  EXPECT_NE(cell_at(strict, 3.75, 0.05), kFree);
  EXPECT_NE(cell_at(rule, 3.75, 0.05), kFree);
  EXPECT_EQ(cell_at(rule, 3.05, 0.05), kOccupied);  // the body's front face
  // Open floor in view: free under every rule.
  EXPECT_EQ(cell_at(strict, 2.05, 0.05), kFree);
  EXPECT_EQ(cell_at(rule, 2.05, 0.05), kFree);
  // Just in front of the camera the lowest layer is out of view (the field of view's lower edge
  // is 0.2 m up 0.4 m ahead).
  EXPECT_NE(cell_at(strict, 0.35, 0.05), kFree);
  EXPECT_EQ(cell_at(rule, 0.35, 0.05), kFree);
  // Under and behind the robot only the footprint says anything.
  EXPECT_NE(cell_at(rule, -0.15, 0.05), kFree);
  EXPECT_EQ(cell_at(robot, -0.15, 0.05), kFree);
  EXPECT_EQ(cell_at(robot, 2.05, 0.05), kFree);
  EXPECT_EQ(cell_at(robot, 3.75, 0.05), cell_at(rule, 3.75, 0.05));
}
