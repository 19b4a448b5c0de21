#include <gtest/gtest.h>

#include <fstream>

#include "core/error.hpp"
#include "detect/class_names.hpp"
#include "detect/dynamic_classes.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::detect {
namespace {

TEST(ClassNames, DarknetSpellingsMapToCanonicalCoco) {
  EXPECT_EQ(canonical_coco_label("motorbike"), "motorcycle");
  EXPECT_EQ(canonical_coco_label("tvmonitor"), "tv");
  EXPECT_EQ(canonical_coco_label("diningtable"), "dining table");
  EXPECT_EQ(canonical_coco_label("body"), "person");
  EXPECT_EQ(canonical_coco_label("chair"), "chair");
  EXPECT_EQ(coco_class_id("person"), 0);
  EXPECT_EQ(coco_class_id("motorbike"), 3);
  EXPECT_EQ(coco_class_id("toothbrush"), 79);
  EXPECT_EQ(coco_class_id("unicorn"), -1);
  EXPECT_EQ(coco_class_names().size(), 80u);
}

TEST(ClassNames, ShippedCocoNamesMatchTheCanonicalOrder) {
  const auto names =
      read_class_names((test::shared_dir() / "models/yolo-fastest/v1.1_coco/coco.names").string());
  EXPECT_EQ(names, coco_class_names());
  const auto body =
      read_class_names((test::shared_dir() / "models/yolo-fastest/v1.1_body/body.names").string());
  EXPECT_EQ(body, std::vector<std::string>{"person"});
}

TEST(ClassNames, BadFilesNameFileAndLine) {
  const auto dir = test::temp_dir("class_names");
  const std::string missing = (dir / "missing.names").string();
  try {
    read_class_names(missing);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  const std::string gap = (dir / "gap.names").string();
  std::ofstream(gap) << "person\n\nbicycle\n";
  try {
    read_class_names(gap);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(gap + ":2"), std::string::npos) << e.what();
  }
  // Trailing blank lines and CRLF are fine.
  const std::string crlf = (dir / "crlf.names").string();
  std::ofstream(crlf) << "person\r\ntraffic light\r\n\n";
  EXPECT_EQ(read_class_names(crlf), (std::vector<std::string>{"person", "traffic light"}));
}

TEST(DynamicClasses, DefaultListAndAliases) {
  EXPECT_TRUE(is_dynamic_class("person"));
  EXPECT_TRUE(is_dynamic_class("motorbike"));  // Darknet spelling
  EXPECT_TRUE(is_dynamic_class("cow"));
  EXPECT_FALSE(is_dynamic_class("chair"));
  EXPECT_FALSE(is_dynamic_class("tvmonitor"));
  EXPECT_EQ(default_dynamic_classes().size(), 12u);
  const DynamicClassList custom({"chair", "person", "chair"});
  EXPECT_TRUE(custom.is_dynamic_class("chair"));
  EXPECT_FALSE(custom.is_dynamic_class("dog"));
  EXPECT_EQ(custom.labels().size(), 2u);
}

TEST(DynamicClasses, SplitByRoleKeepsWeakObjectsAndDropsWeakMovers) {
  const auto box = [](const char* label, float score) {
    Detection d;
    d.label = label;
    d.score = score;
    d.x_max = d.y_max = 10.0f;
    return d;
  };
  const std::vector<Detection> boxes = {box("person", 0.9f), box("person", 0.2f),
                                        box("chair", 0.16f), box("car", 0.25f),
                                        box("dining table", 0.6f)};
  const DetectionRoles r = split_by_role(boxes, DynamicClassList(), kMoverMinScore);
  ASSERT_EQ(r.movers.size(), 2u);
  EXPECT_EQ(r.movers[0].label, "person");
  EXPECT_FLOAT_EQ(r.movers[0].score, 0.9f);
  EXPECT_EQ(r.movers[1].label, "car");  // at the threshold counts
  ASSERT_EQ(r.objects.size(), 2u);
  EXPECT_EQ(r.objects[0].label, "chair");
  EXPECT_EQ(r.objects[1].label, "dining table");
  // A custom list moves the chair to the movers, where its score is too weak.
  const DetectionRoles c = split_by_role(boxes, DynamicClassList({"chair"}), kMoverMinScore);
  EXPECT_TRUE(c.movers.empty());
  EXPECT_EQ(c.objects.size(), 4u);
}

}  // namespace
}  // namespace kestrel::detect
