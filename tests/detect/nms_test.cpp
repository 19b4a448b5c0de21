#include <gtest/gtest.h>

#include "detect/nms.hpp"

namespace kestrel::detect {
namespace {

Detection box(const std::string& label, int id, float score, float x0, float y0, float x1,
              float y1) {
  Detection d;
  d.label = label;
  d.class_id = id;
  d.score = score;
  d.x_min = x0;
  d.y_min = y0;
  d.x_max = x1;
  d.y_max = y1;
  return d;
}

TEST(Iou, KnownValues) {
  const Detection a = box("person", 0, 1, 0, 0, 10, 10);
  EXPECT_FLOAT_EQ(iou(a, a), 1.0f);
  EXPECT_FLOAT_EQ(iou(a, box("person", 0, 1, 5, 0, 15, 10)), 50.0f / 150.0f);
  EXPECT_FLOAT_EQ(iou(a, box("person", 0, 1, 10, 0, 20, 10)), 0.0f);  // touching edges
}

TEST(Nms, SuppressesOverlapsWithinAClassOnly) {
  const std::vector<Detection> in = {
      box("person", 0, 0.6f, 0, 0, 100, 200),  // overlaps the 0.9 person: IoU 0.93
      box("person", 0, 0.9f, 5, 5, 100, 200),
      box("bicycle", 1, 0.5f, 0, 0, 100, 200),   // same place, other class: kept
      box("person", 0, 0.7f, 300, 0, 400, 200),  // another person, no overlap: kept
      box("person", 0, 0.8f, 50, 0, 150, 200),   // IoU with the 0.9 person ~0.33: kept at 0.45
  };
  const auto out = non_max_suppression(in, 0.45f);
  ASSERT_EQ(out.size(), 4u);
  EXPECT_FLOAT_EQ(out[0].score, 0.9f);
  EXPECT_FLOAT_EQ(out[1].score, 0.8f);
  EXPECT_FLOAT_EQ(out[2].score, 0.7f);
  EXPECT_EQ(out[3].label, "bicycle");
  // A stricter threshold also removes the partly overlapping person.
  EXPECT_EQ(non_max_suppression(in, 0.3f).size(), 3u);
  EXPECT_TRUE(non_max_suppression({}, 0.45f).empty());
}

TEST(Nms, UnknownClassesAreKeptApartByLabel) {
  const std::vector<Detection> in = {box("gizmo", -1, 0.9f, 0, 0, 10, 10),
                                     box("widget", -1, 0.8f, 0, 0, 10, 10),
                                     box("gizmo", -1, 0.7f, 0, 0, 10, 10)};
  const auto out = non_max_suppression(in, 0.5f);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].label, "gizmo");
  EXPECT_EQ(out[1].label, "widget");
}

}  // namespace
}  // namespace kestrel::detect
