#include "dynamic/mover_silhouette.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <stdexcept>

#include "dynamic/object_depth.hpp"

namespace kestrel::dynamic {
namespace {

constexpr double kScale = 1000.0;  // 1 mm per unit

// A wall at 5 m with a walker at 2 m standing in front of it (x 100..139, y 60..179).
Image scene_depth() {
  Image d = Image::allocate(320, 240, 1, PixelType::kU16);
  for (int v = 0; v < d.height; ++v) {
    auto* row = d.row<std::uint16_t>(v);
    for (int u = 0; u < d.width; ++u) {
      row[u] = 5000;
      if (u >= 100 && u < 140 && v >= 60 && v < 180) row[u] = 2000;
    }
  }
  return d;
}

std::uint8_t at(const Image& m, int u, int v) { return m.row<std::uint8_t>(v)[u]; }

int count_set(const Image& m) {
  int n = 0;
  for (int v = 0; v < m.height; ++v) {
    for (int u = 0; u < m.width; ++u) n += at(m, u, v) != 0;
  }
  return n;
}

// The walker's box (x 80..159, y 50..189) in scene_depth, grown by grow_px.
Image walker_silhouette(int grow_px) {
  MoverSilhouetteOptions opt;
  opt.grow_px = grow_px;
  return mover_silhouette(scene_depth(), kScale, {{80.0f, 50.0f, 160.0f, 190.0f}}, opt,
                          DynamicFilterOptions{});
}

// The walker's box holds as much wall as walker: the silhouette is the walker alone.
TEST(MoverSilhouette, IsTheObjectsDepthInsideItsBoxNotTheSceneryBehind) {
  const Image m = walker_silhouette(0);
  ASSERT_EQ(m.type, PixelType::kU8);
  ASSERT_EQ(m.width, scene_depth().width);
  EXPECT_EQ(count_set(m), 40 * 120);
  EXPECT_EQ(at(m, 100, 60), 255);
  EXPECT_EQ(at(m, 139, 179), 255);
  EXPECT_EQ(at(m, 99, 100), 0);   // the wall beside the walker, inside the box
  EXPECT_EQ(at(m, 120, 185), 0);  // ... and below it
}

TEST(MoverSilhouette, GrowsByTheMarginTheNextFrameNeeds) {
  const Image m = walker_silhouette(5);
  EXPECT_EQ(count_set(m), 50 * 130);
  EXPECT_EQ(at(m, 95, 55), 255);
  EXPECT_EQ(at(m, 94, 100), 0);
}

TEST(MoverSilhouette, ParkedBoxesAndBoxesWithoutDepthHaveNone) {
  Image depth = scene_depth();
  MoverSilhouetteOptions opt;
  BoxRegion parked{80.0f, 50.0f, 160.0f, 190.0f};
  parked.parked = true;
  EXPECT_EQ(count_set(mover_silhouette(depth, kScale, {parked}, opt, DynamicFilterOptions{})), 0);
  // A car beyond the sensor's range: no readings in its box.
  for (int v = 0; v < 40; ++v) {
    auto* row = depth.row<std::uint16_t>(v);
    for (int u = 200; u < 300; ++u) row[u] = 0;
  }
  EXPECT_EQ(count_set(mover_silhouette(depth, kScale, {{200.0f, 0.0f, 300.0f, 40.0f}}, opt,
                                       DynamicFilterOptions{})),
            0);
  EXPECT_EQ(count_set(mover_silhouette(depth, kScale, {}, opt, DynamicFilterOptions{})), 0);
}

TEST(MoverSilhouette, RejectsWhatItCannotRead) {
  const Image depth = scene_depth();
  const Image grey = Image::allocate(320, 240, 1, PixelType::kU8);
  const std::vector<BoxRegion> box = {{80.0f, 50.0f, 160.0f, 190.0f}};
  EXPECT_THROW(mover_silhouette(grey, kScale, box, {}, DynamicFilterOptions{}),
               std::invalid_argument);
  EXPECT_THROW(mover_silhouette(depth, 0.0, box, {}, DynamicFilterOptions{}),
               std::invalid_argument);
  MoverSilhouetteOptions bad;
  bad.grow_px = -1;
  EXPECT_THROW(mover_silhouette(depth, kScale, box, bad, DynamicFilterOptions{}),
               std::invalid_argument);
  bad = {};
  bad.min_readings = 0;
  EXPECT_THROW(validate(bad, DynamicFilterOptions{}), std::invalid_argument);
  DynamicFilterOptions no_band;
  no_band.foreground_band_m = 0.0;
  EXPECT_THROW(validate(MoverSilhouetteOptions{}, no_band), std::invalid_argument);
  EXPECT_NO_THROW(validate(MoverSilhouetteOptions{}, DynamicFilterOptions{}));
}

// The object's depth is the largest surface among the core's readings, not their median: a
// core half walker (2 m), half wall (5 m) with the walker a little larger reads 2 m.
TEST(ObjectDepth, TheLargestSurfaceOfACoreHalfObjectHalfWall) {
  Image depth = Image::allocate(100, 100, 1, PixelType::kU16);
  for (int v = 0; v < 100; ++v) {
    auto* row = depth.row<std::uint16_t>(v);
    for (int u = 0; u < 100; ++u) row[u] = u < 54 ? 2000 + (u % 3) * 10 : 5000;
  }
  const std::vector<double> s =
      largest_surface(depth, kScale, {0, 0, 100, 100}, DynamicFilterOptions{});
  ASSERT_FALSE(s.empty());
  EXPECT_NEAR(s.front(), 2.0, 1e-9);
  EXPECT_NEAR(s.back(), 2.02, 1e-9);
  const BoxRegion core = box_core({0, 0, 100, 200});
  EXPECT_FLOAT_EQ(core.x_min, 25.0f);
  EXPECT_FLOAT_EQ(core.x_max, 75.0f);
  EXPECT_FLOAT_EQ(core.y_min, 30.0f);
  EXPECT_FLOAT_EQ(core.y_max, 130.0f);
}

}  // namespace
}  // namespace kestrel::dynamic
