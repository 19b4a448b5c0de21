// YOLO-Fastest on real images: the shared TUM frame with its person mask, the Darknet/VOC
// sample photos and the pedestrian video.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <opencv2/videoio.hpp>
#include <set>

#include "core/error.hpp"
#include "detect/class_names.hpp"
#include "detect/dynamic_classes.hpp"
#include "detect/yolo_fastest.hpp"
#include "io/cv_image.hpp"
#include "io/image_io.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::detect {
namespace {

const std::string kTumRgb = "tum_fr3/frame/rgb_1341846313.592026.png";
const std::string kTumMask = "tum_fr3/frame/static_mask_1341846313.592026.png";

std::string models_dir() { return (test::shared_dir() / "models/yolo-fastest").string(); }

Image load(const std::string& rel) {
  return io::load_image(test::shared_data(rel).string(), io::ImageKind::kColor);
}

void print(const std::string& what, const DetectionSet& set) {
  std::cout << what << ": " << set.boxes.size() << " boxes, " << set.latency_ms << " ms\n";
  for (const Detection& d : set.boxes) {
    std::cout << "  " << d.label << " " << d.score << " [" << d.x_min << " " << d.y_min << " "
              << d.x_max << " " << d.y_max << "]\n";
  }
}

std::map<std::string, float> best_score_per_label(const DetectionSet& set) {
  std::map<std::string, float> best;
  for (const Detection& d : set.boxes) best[d.label] = std::max(best[d.label], d.score);
  return best;
}

// Fraction of the mask's person pixels (value 0) inside the union of the person boxes.
double person_coverage(const DetectionSet& set, const Image& mask) {
  long total = 0, covered = 0;
  for (int y = 0; y < mask.height; ++y) {
    const std::uint8_t* row = mask.row<std::uint8_t>(y);
    for (int x = 0; x < mask.width; ++x) {
      if (row[x] != 0) continue;
      ++total;
      const double px = x + 0.5, py = y + 0.5;
      for (const Detection& d : set.boxes) {
        if (d.label == "person" && px >= d.x_min && px < d.x_max && py >= d.y_min && py < d.y_max) {
          ++covered;
          break;
        }
      }
    }
  }
  return total > 0 ? static_cast<double>(covered) / static_cast<double>(total) : 0.0;
}

class YoloFastestTest : public ::testing::Test {
 protected:
  static YoloFastest& v11() {
    static YoloFastest detector(models_dir());
    return detector;
  }
};

TEST_F(YoloFastestTest, TumFramePersonBoxesCoverThePersonMask) {
  const Image rgb = load(kTumRgb);
  const Image mask = io::load_image(test::shared_data(kTumMask).string(), io::ImageKind::kGrey);
  const DetectionSet set = v11().detect(rgb, 42);
  print("tum_fr3 v1.1@320", set);
  EXPECT_EQ(set.t, 42);
  EXPECT_GT(set.latency_ms, 0.0);
  const double coverage = person_coverage(set, mask);
  std::cout << "person-mask coverage v1.1@320: " << coverage << "\n";
  RecordProperty("person_mask_coverage", std::to_string(coverage));
  EXPECT_GE(coverage, 0.90);
  // Two people in the frame.
  const auto persons = std::count_if(set.boxes.begin(), set.boxes.end(),
                                     [](const Detection& d) { return d.label == "person"; });
  EXPECT_EQ(persons, 2);
}

TEST_F(YoloFastestTest, LetterboxFindsTheSamePeopleAsStretch) {
  YoloFastestOptions o;
  o.resize = InputResize::kLetterbox;
  YoloFastest letterbox(models_dir(), o);
  const Image rgb = load(kTumRgb);
  const DetectionSet a = v11().detect(rgb, 0);
  const DetectionSet b = letterbox.detect(rgb, 0);
  print("tum_fr3 v1.1@320 letterbox", b);
  int matched = 0;
  for (const Detection& p : a.boxes) {
    if (p.label != "person") continue;
    float best = 0;
    for (const Detection& q : b.boxes) {
      if (q.label == "person") best = std::max(best, iou(p, q));
    }
    std::cout << "person IoU stretch vs letterbox: " << best << "\n";
    EXPECT_GT(best, 0.7f);
    ++matched;
  }
  EXPECT_EQ(matched, 2);
  const Image mask = io::load_image(test::shared_data(kTumMask).string(), io::ImageKind::kGrey);
  EXPECT_GE(person_coverage(b, mask), 0.85);
}

TEST_F(YoloFastestTest, XlAndBodyModelsAlsoCoverThePersonMask) {
  const Image rgb = load(kTumRgb);
  const Image mask = io::load_image(test::shared_data(kTumMask).string(), io::ImageKind::kGrey);
  for (YoloModel m : {YoloModel::kV11Xl, YoloModel::kBody}) {
    YoloFastestOptions o;
    o.model = m;
    YoloFastest det(models_dir(), o);
    const DetectionSet set = det.detect(rgb, 0);
    const double coverage = person_coverage(set, mask);
    std::cout << det.name() << " person-mask coverage: " << coverage << "\n";
    EXPECT_GE(coverage, 0.90) << det.name();
    if (m == YoloModel::kBody) {
      EXPECT_EQ(det.class_names(), std::vector<std::string>{"person"});
      for (const Detection& d : set.boxes) EXPECT_EQ(d.label, "person");
    }
  }
}

TEST_F(YoloFastestTest, Size416Works) {
  YoloFastestOptions o;
  o.input_size = 416;
  YoloFastest det(models_dir(), o);
  EXPECT_EQ(det.name(), "yolo-fastest-v1.1@416");
  const DetectionSet set = det.detect(load(kTumRgb), 0);
  print("tum_fr3 v1.1@416", set);
  // At 416 the model also reports a part of one person as a second box, so only coverage and
  // "at least the two people" are required.
  EXPECT_GE(std::count_if(set.boxes.begin(), set.boxes.end(),
                          [](const Detection& d) { return d.label == "person"; }),
            2);
  const Image mask = io::load_image(test::shared_data(kTumMask).string(), io::ImageKind::kGrey);
  const double coverage = person_coverage(set, mask);
  std::cout << "person-mask coverage v1.1@416: " << coverage << "\n";
  EXPECT_GE(coverage, 0.85);
}

TEST_F(YoloFastestTest, SamplePhotosGiveTheirClasses) {
  // Facts that hold for v1.1 at 320 (checked against the model's raw output; the Darknet
  // sample's horse in person.jpg is seen by this small model as a sheep, so it is only required
  // to be some animal).
  {
    const DetectionSet s = v11().detect(load("images/person.jpg"), 0);
    print("person.jpg", s);
    const auto best = best_score_per_label(s);
    ASSERT_TRUE(best.contains("person"));
    EXPECT_GT(best.at("person"), 0.9f);
    ASSERT_TRUE(best.contains("dog"));
    EXPECT_GT(best.at("dog"), 0.5f);
    // The animal on the right (the horse, x ~ 400..600).
    EXPECT_TRUE(std::any_of(s.boxes.begin(), s.boxes.end(), [](const Detection& d) {
      return d.label != "person" && d.label != "dog" && is_dynamic_class(d.label) &&
             d.x_min > 350 && d.x_max > 550;
    }));
  }
  {
    const DetectionSet s = v11().detect(load("images/dog.jpg"), 0);
    print("dog.jpg", s);
    const auto best = best_score_per_label(s);
    ASSERT_TRUE(best.contains("dog"));
    ASSERT_TRUE(best.contains("bicycle"));
    ASSERT_TRUE(best.contains("car") || best.contains("truck"));
    EXPECT_GT(best.at("dog"), 0.5f);
    // The car is in the top right.
    EXPECT_TRUE(std::any_of(s.boxes.begin(), s.boxes.end(), [](const Detection& d) {
      return (d.label == "car" || d.label == "truck") && d.score > 0.5f && d.x_min > 400 &&
             d.y_max < 250;
    }));
  }
  {
    const DetectionSet s = v11().detect(load("images/horses.jpg"), 0);
    print("horses.jpg", s);
    ASSERT_FALSE(s.boxes.empty());
    EXPECT_EQ(s.boxes.front().label, "horse");
    EXPECT_GE(std::count_if(s.boxes.begin(), s.boxes.end(),
                            [](const Detection& d) { return d.label == "horse"; }),
              3);
    for (const Detection& d : s.boxes) EXPECT_TRUE(is_dynamic_class(d.label)) << d.label;
  }
  {
    const DetectionSet s = v11().detect(load("images/000004.jpg"), 0);  // a row of parked cars
    EXPECT_GE(s.boxes.size(), 8u);
    for (const Detection& d : s.boxes) EXPECT_EQ(d.label, "car");
  }
  {
    const auto best = best_score_per_label(v11().detect(load("images/000230.jpg"), 0));
    ASSERT_TRUE(best.contains("person"));
    EXPECT_GT(best.at("person"), 0.9f);
    EXPECT_TRUE(best.contains("bicycle") || best.contains("motorcycle"));
  }
}

TEST_F(YoloFastestTest, GreyImagesAndEmptyImages) {
  const Image rgb = load(kTumRgb);
  const Image grey = io::load_image(test::shared_data(kTumRgb).string(), io::ImageKind::kGrey);
  ASSERT_EQ(grey.channels, 1);
  const DetectionSet set = v11().detect(grey, 5);
  EXPECT_EQ(std::count_if(set.boxes.begin(), set.boxes.end(),
                          [](const Detection& d) { return d.label == "person"; }),
            2);
  const DetectionSet none = v11().detect(Image{}, 77);
  EXPECT_EQ(none.t, 77);
  EXPECT_TRUE(none.boxes.empty());
  EXPECT_THROW(v11().detect(Image::allocate(8, 8, 1, PixelType::kU16), 0), std::invalid_argument);
  // Boxes are clipped to the image.
  for (const Detection& d : v11().detect(rgb, 0).boxes) {
    EXPECT_GE(d.x_min, 0);
    EXPECT_LE(d.x_max, rgb.width);
    EXPECT_GE(d.y_min, 0);
    EXPECT_LE(d.y_max, rgb.height);
    EXPECT_EQ(d.class_id, coco_class_id(d.label));
  }
}

TEST_F(YoloFastestTest, PedestrianVideoFromARaisedCamera) {
  // The first 20 frames (2 s) show three walkers, a fourth entering on the right from about
  // frame 11, small (about 30 x 80 px in 768 x 576) and seen from above. At the default
  // threshold (0.25) the model also calls some cones and bollards "person"; above 0.5 it reports
  // the walkers and, in a few frames, the sign post one of them passes behind.
  cv::VideoCapture cap(test::shared_data("video/vtest.avi").string());
  ASSERT_TRUE(cap.isOpened()) << "OpenCV videoio cannot read vtest.avi";
  cv::Mat frame;
  int frames = 0, all = 0, confident = 0, min_confident = 1000, max_confident = 0;
  std::string per_frame;
  for (int i = 0; i < 20 && cap.read(frame); ++i) {
    const DetectionSet s = v11().detect(io::to_image(frame), i);
    int n = 0, c = 0;
    for (const Detection& d : s.boxes) {
      if (d.label != "person") continue;
      ++n;
      c += d.score >= 0.5f;
    }
    per_frame += " " + std::to_string(n) + "/" + std::to_string(c);
    ++frames;
    all += n;
    confident += c;
    min_confident = std::min(min_confident, c);
    max_confident = std::max(max_confident, c);
  }
  std::cout << "vtest.avi persons per frame, score >= 0.25 / >= 0.5 (v1.1@320):" << per_frame
            << "\nmean " << static_cast<double>(all) / frames << " / "
            << static_cast<double>(confident) / frames << "\n";
  EXPECT_EQ(frames, 20);
  EXPECT_GE(min_confident, 2);
  EXPECT_LE(max_confident, 5);
  EXPECT_GE(static_cast<double>(confident) / frames, 2.5);
}

TEST(YoloFastestErrors, MissingModelFilesAreNamed) {
  const auto dir = test::temp_dir("yolo_missing");
  try {
    YoloFastest det(dir.string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "v1.1_coco/yolo-fastest-1.1.cfg").string()),
              std::string::npos)
        << e.what();
  }
  // cfg present, weights missing: the weights file is named.
  std::filesystem::create_directories(dir / "v1.1_coco");
  std::filesystem::copy_file(
      test::shared_dir() / "models/yolo-fastest/v1.1_coco/yolo-fastest-1.1.cfg",
      dir / "v1.1_coco/yolo-fastest-1.1.cfg");
  try {
    YoloFastest det(dir.string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("yolo-fastest-1.1.weights"), std::string::npos)
        << e.what();
  }
  // A truncated weights file is a load error that names it.
  { std::ofstream(dir / "v1.1_coco/yolo-fastest-1.1.weights") << "not weights"; }
  std::filesystem::copy_file(test::shared_dir() / "models/yolo-fastest/v1.1_coco/coco.names",
                             dir / "v1.1_coco/coco.names");
  try {
    YoloFastest det(dir.string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("yolo-fastest-1.1.weights"), std::string::npos)
        << e.what();
  }
}

TEST(YoloFastestErrors, BadOptionsNameTheField) {
  YoloFastestOptions o;
  o.input_size = 300;
  try {
    YoloFastest det(models_dir(), o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("input_size"), std::string::npos) << e.what();
  }
  o = {};
  o.conf_threshold = 1.5f;
  EXPECT_THROW(YoloFastest(models_dir(), o), Error);
}

TEST(YoloFastestPaths, FindModelsDirHonoursKestrelShared) {
  const char* old = std::getenv("KESTREL_SHARED");
  const std::string saved = old ? old : "";
  const auto fake = test::temp_dir("fake_shared");
  ::setenv("KESTREL_SHARED", fake.c_str(), 1);
  try {
    find_models_dir();
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find((fake / "models/yolo-fastest").string()),
              std::string::npos)
        << e.what();
  }
  std::filesystem::create_directories(fake / "models/yolo-fastest");
  EXPECT_EQ(std::filesystem::path(find_models_dir()),
            (fake / "models/yolo-fastest").lexically_normal());
  if (old) {
    ::setenv("KESTREL_SHARED", saved.c_str(), 1);
  } else {
    ::unsetenv("KESTREL_SHARED");
  }
  EXPECT_TRUE(std::filesystem::is_directory(find_models_dir()));
  EXPECT_TRUE(parse_yolo_model("xl") == YoloModel::kV11Xl);
  EXPECT_FALSE(parse_yolo_model("v2").has_value());
}

}  // namespace
}  // namespace kestrel::detect
