#include "detect/nms.hpp"

#include <algorithm>
#include <map>
#include <opencv2/dnn.hpp>
#include <string>
#include <utility>

namespace kestrel::detect {

std::vector<Detection> non_max_suppression(const std::vector<Detection>& boxes,
                                           float iou_threshold) {
  // Group by class; the key keeps unknown classes (id -1) apart by label.
  std::map<std::pair<int, std::string>, std::vector<std::size_t>> groups;
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const Detection& d = boxes[i];
    groups[{d.class_id, d.class_id >= 0 ? std::string() : d.label}].push_back(i);
  }
  std::vector<Detection> kept;
  std::vector<cv::Rect2d> rects;
  std::vector<float> scores;
  std::vector<int> indices;
  for (const auto& [key, members] : groups) {
    rects.clear();
    scores.clear();
    for (std::size_t i : members) {
      const Detection& d = boxes[i];
      rects.emplace_back(d.x_min, d.y_min, d.width(), d.height());
      scores.push_back(d.score);
    }
    // The caller applied its score threshold; OpenCV keeps scores strictly above this one.
    cv::dnn::NMSBoxes(rects, scores, 0.0f, iou_threshold, indices);
    for (int k : indices) kept.push_back(boxes[members[static_cast<std::size_t>(k)]]);
  }
  std::stable_sort(kept.begin(), kept.end(),
                   [](const Detection& a, const Detection& b) { return a.score > b.score; });
  return kept;
}

}  // namespace kestrel::detect
