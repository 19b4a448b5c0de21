// eval/object_metrics and eval/occupancy_metrics on hand-made inputs whose scores are known.
#include <gtest/gtest.h>

#include "eval/object_metrics.hpp"
#include "eval/occupancy_metrics.hpp"

namespace kestrel::eval {
namespace {

ObjectBox box(const std::string& label, double x, double y) {
  return {label, Vec3(x, y, 0.4), Vec3(1.0, 0.5, 0.8), 0.0, 3};
}

TEST(ObjectMetrics, DuplicatesLowerPrecisionAndWrongLabelsLowerClassAccuracy) {
  const std::vector<ObjectBox> truth = {box("chair", 0, 0), box("table", 3, 0), box("bed", 6, 0)};
  std::vector<ObjectBox> reported = {box("chair", 0.1, 0), box("chair", 0.2, 0.1),
                                     box("sofa", 3.0, 0.05)};
  reported[0].size = Vec3(1.1, 0.5, 0.8);  // 10% along, exact across and vertical
  const ObjectScores s = score_objects(truth, reported);
  EXPECT_EQ(s.matched, 2);
  EXPECT_DOUBLE_EQ(s.recall, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(s.precision, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(s.class_correct, 0.5);
  EXPECT_NEAR(s.center_error_median, 0.1, 1e-12);
  EXPECT_NEAR(s.size_error_median, 0.0, 1e-12);
  ASSERT_EQ(s.lines.size(), 4u);  // three truths, one extra
  EXPECT_EQ(s.lines[2], "bed missed");
}

TEST(ObjectMetrics, FarReportsDoNotMatch) {
  const ObjectScores s = score_objects({box("chair", 0, 0)}, {box("chair", 0.6, 0)});
  EXPECT_EQ(s.matched, 0);
  EXPECT_EQ(s.recall, 0.0);
  EXPECT_EQ(s.precision, 0.0);
}

TEST(OccupancyMetrics, WallRasterizesAndScores) {
  const GridFrame f{20, 20, 0.1, Vec2(0, 0)};
  // A vertical wall along x = 1.05 from y = 0.25 to 1.75, 0 .. 2 m high.
  const std::vector<WorldTriangle> wall = {
      {Vec3(1.05, 0.25, 0), Vec3(1.05, 1.75, 0), Vec3(1.05, 1.75, 2)},
      {Vec3(1.05, 0.25, 0), Vec3(1.05, 1.75, 2), Vec3(1.05, 0.25, 2)}};
  const CellMask truth = rasterize_triangles(wall, f, 0.1, 1.5);
  int n = 0;
  for (std::uint8_t c : truth.cells) n += c;
  EXPECT_EQ(n, 16);  // y cells 2 .. 17 of column 10
  EXPECT_TRUE(truth.at(10, 5));
  EXPECT_FALSE(truth.at(9, 5));

  CellMask known(f), est(f);
  std::fill(known.cells.begin(), known.cells.end(), 1);
  for (int y = 2; y < 18; ++y) est.cells[f.index(y < 10 ? 10 : 11, y)] = 1;  // half off by one
  EXPECT_DOUBLE_EQ(occupancy_iou(est, known, truth), 1.0);
  est.cells[f.index(3, 3)] = 1;  // a false alarm far from the wall
  EXPECT_DOUBLE_EQ(occupancy_iou(est, known, truth), 16.0 / 17.0);

  const std::vector<Vec3> voxels = {Vec3(1.05, 1.0, 1.0), Vec3(0.35, 0.35, 1.0),
                                    Vec3(0.35, 0.35, 3.0), Vec3(1.75, 1.75, 1.0)};
  const std::vector<std::vector<Vec2>> paths = {{Vec2(0, 0.3), Vec2(0.6, 0.3)}};
  // One voxel on the wall, one on the path, one above the band, one elsewhere.
  EXPECT_DOUBLE_EQ(dynamic_residue(voxels, truth, paths, 0.5, 0.1, 1.5), 1.0 / 3.0);
}

}  // namespace
}  // namespace kestrel::eval
