#pragma once
// Which object classes may move by themselves. Their boxes mark features the dynamic filter
// must distrust; every other class (chair, tv, ...) is treated as scenery.
#include <string>
#include <string_view>
#include <vector>

namespace kestrel::detect {

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

}  // namespace kestrel::detect
