// The simulated people must look like people to a real detector: YOLO-Fastest 1.1 (COCO, the
// Darknet files read by OpenCV DNN) has to find at least 70 % of the visible, unoccluded people
// taller than 60 px in cafe and uav-zigzag.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "sim/simulator.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::sim {
namespace {

struct Rect {
  double x0, y0, x1, y1;
};

double iou(const Rect& a, const Rect& b) {
  const double w = std::min(a.x1, b.x1) - std::max(a.x0, b.x0),
               h = std::min(a.y1, b.y1) - std::max(a.y0, b.y0);
  if (w <= 0 || h <= 0) return 0.0;
  const double inter = w * h;
  return inter / ((a.x1 - a.x0) * (a.y1 - a.y0) + (b.x1 - b.x0) * (b.y1 - b.y0) - inter);
}

std::vector<Rect> detect_people(cv::dnn::Net& net, const cv::Mat& bgr) {
  const cv::Mat blob =
      cv::dnn::blobFromImage(bgr, 1.0 / 255.0, cv::Size(320, 320), cv::Scalar(), true, false);
  net.setInput(blob);
  std::vector<cv::Mat> outs;
  net.forward(outs, net.getUnconnectedOutLayersNames());
  std::vector<cv::Rect> boxes;
  std::vector<float> scores;
  for (const cv::Mat& out : outs) {
    for (int r = 0; r < out.rows; ++r) {
      const float* row = out.ptr<float>(r);
      const float score = row[5];  // class 0: person (already times objectness)
      if (score < 0.25f) continue;
      const float cx = row[0] * bgr.cols, cy = row[1] * bgr.rows, w = row[2] * bgr.cols,
                  h = row[3] * bgr.rows;
      boxes.emplace_back(static_cast<int>(cx - w / 2), static_cast<int>(cy - h / 2),
                         static_cast<int>(w), static_cast<int>(h));
      scores.push_back(score);
    }
  }
  std::vector<int> keep;
  cv::dnn::NMSBoxes(boxes, scores, 0.25f, 0.45f, keep);
  std::vector<Rect> people;
  for (int i : keep) {
    const cv::Rect& b = boxes[static_cast<std::size_t>(i)];
    people.push_back({static_cast<double>(b.x), static_cast<double>(b.y),
                      static_cast<double>(b.x + b.width), static_cast<double>(b.y + b.height)});
  }
  return people;
}

void check_scenario(const std::string& name, int stride) {
  const auto dir = test::shared_dir() / "models" / "yolo-fastest" / "v1.1_coco";
  const auto cfg = dir / "yolo-fastest-1.1.cfg", weights = dir / "yolo-fastest-1.1.weights";
  if (!std::filesystem::exists(cfg) || !std::filesystem::exists(weights))
    GTEST_SKIP() << "no model at " << dir;
  cv::dnn::Net net = cv::dnn::readNetFromDarknet(cfg.string(), weights.string());
  Simulator sim(load_scenario(name));
  int eligible = 0, found = 0;
  for (int k = 0; k < sim.frame_count(); k += stride) {
    const SimFrame f = sim.render(k);
    const cv::Mat bgr(f.color.height, f.color.width, CV_8UC3, f.color.data->data());
    std::vector<Rect> dets;
    bool detected = false;
    for (const SimBox& b : f.boxes) {
      if (b.label != "person" || b.occluded > 0.05 || b.y_max - b.y_min <= 60) continue;
      // Cut by the image border is not "visible" in full either.
      if (b.x_min <= 1 || b.y_min <= 1 || b.x_max >= f.color.width - 1 ||
          b.y_max >= f.color.height - 1)
        continue;
      if (!detected) {
        dets = detect_people(net, bgr);
        detected = true;
      }
      ++eligible;
      const Rect truth{static_cast<double>(b.x_min), static_cast<double>(b.y_min),
                       static_cast<double>(b.x_max), static_cast<double>(b.y_max)};
      double best = 0.0;
      for (const Rect& d : dets) best = std::max(best, iou(truth, d));
      const bool hit = best >= 0.4;
      found += hit;
      if (std::getenv("KESTREL_YOLO_DEBUG")) {
        std::printf("frame %d id %d h %d %s iou %.2f dets %zu\n", k, b.instance, b.y_max - b.y_min,
                    hit ? "hit" : "MISS", best, dets.size());
      }
    }
  }
  std::printf("%s: detected %d of %d visible unoccluded people taller than 60 px (%.0f %%)\n",
              name.c_str(), found, eligible, eligible ? 100.0 * found / eligible : 0.0);
  ASSERT_GE(eligible, 20) << "too few people to judge";
  EXPECT_GE(static_cast<double>(found) / eligible, 0.70);
}

TEST(YoloOnSimulatedPeople, CafeAtLeast70Percent) { check_scenario("cafe", 10); }
TEST(YoloOnSimulatedPeople, UavZigzagAtLeast70Percent) { check_scenario("uav-zigzag", 15); }

}  // namespace
}  // namespace kestrel::sim
