#include "detect/dynamic_classes.hpp"

#include <algorithm>

#include "detect/class_names.hpp"

namespace kestrel::detect {

const std::vector<std::string>& default_dynamic_classes() {
  static const std::vector<std::string> kDefault = {"person", "bicycle", "car",   "motorcycle",
                                                    "bus",    "truck",   "dog",   "cat",
                                                    "horse",  "bird",    "sheep", "cow"};
  return kDefault;
}

const std::vector<std::string>& default_parkable_classes() {
  static const std::vector<std::string> kDefault = {"bicycle", "car", "motorcycle", "bus", "truck"};
  return kDefault;
}

DynamicClassList::DynamicClassList() : DynamicClassList(default_dynamic_classes()) {}

DynamicClassList::DynamicClassList(std::vector<std::string> labels) {
  for (std::string& l : labels) l = canonical_coco_label(l);
  std::sort(labels.begin(), labels.end());
  labels.erase(std::unique(labels.begin(), labels.end()), labels.end());
  labels_ = std::move(labels);
}

bool DynamicClassList::is_dynamic_class(std::string_view label) const {
  return std::binary_search(labels_.begin(), labels_.end(), canonical_coco_label(label));
}

bool is_dynamic_class(std::string_view label) {
  static const DynamicClassList kList;
  return kList.is_dynamic_class(label);
}

DetectionRoles split_by_role(const std::vector<Detection>& boxes, const DynamicClassList& dynamic,
                             float mover_min_score) {
  DetectionRoles out;
  for (const Detection& d : boxes) {
    if (!dynamic.is_dynamic_class(d.label)) {
      out.objects.push_back(d);
    } else if (d.score >= mover_min_score) {
      out.movers.push_back(d);
    }
  }
  return out;
}

}  // namespace kestrel::detect
