#pragma once
// Which object classes may move by themselves. Their boxes mark features the dynamic filter
// must distrust; every other class (chair, tv, ...) is treated as scenery.
#include <string>
#include <string_view>
#include <vector>

#include "detect/detection.hpp"

namespace kestrel::detect {

// The class score a dynamic-class box needs to count as a mover's (YOLO's usual 0.25). The
// pipeline's detector reports boxes from kPipelineYoloMinScore up (yolo_fastest.hpp), for the
// object database; a weaker mover box would cost the filter scenery it cannot spare: over nine
// 60 s draws, 0.10 for every class (at 416) made APE worse on six (yolo_fastest.hpp).
inline constexpr float kMoverMinScore = 0.25f;

// person, bicycle, car, motorcycle, bus, truck, dog, cat, horse, bird, sheep, cow.
const std::vector<std::string>& default_dynamic_classes();

// The dynamic classes that park: vehicles (bicycle, car, motorcycle, bus, truck), which stand
// still for hours and are scenery meanwhile (dynamic/parked_boxes.hpp); people and animals
// stand still only to move again.
const std::vector<std::string>& default_parkable_classes();

class DynamicClassList {
 public:
  DynamicClassList();  // default_dynamic_classes()
  explicit DynamicClassList(std::vector<std::string> labels);

  // Labels are compared after canonical_coco_label(), so Darknet's "motorbike" matches
  // "motorcycle".
  bool is_dynamic_class(std::string_view label) const;
  const std::vector<std::string>& labels() const { return labels_; }

 private:
  std::vector<std::string> labels_;  // canonical, sorted, unique
};

// Against the default list.
bool is_dynamic_class(std::string_view label);

// A frame's boxes by role: movers (dynamic classes scoring at least mover_min_score) for the
// dynamic filter, objects (every other class, at the detector's own threshold) for the object
// database. A dynamic-class box below mover_min_score is neither.
struct DetectionRoles {
  std::vector<Detection> movers, objects;
};
DetectionRoles split_by_role(const std::vector<Detection>& boxes, const DynamicClassList& dynamic,
                             float mover_min_score);

}  // namespace kestrel::detect
