#pragma once
// Class names: the canonical COCO list (names as in COCO 2017 annotations, which the simulator
// writes into boxes.csv) and Darknet's .names files, whose few VOC-style spellings
// ("motorbike", "tvmonitor") are mapped to the canonical ones.
#include <string>
#include <string_view>
#include <vector>

namespace kestrel::detect {

// The 80 COCO detection classes in Darknet's order (index = YOLO class id).
const std::vector<std::string>& coco_class_names();
// Index in coco_class_names() of a canonical or Darknet-spelled label; -1 if none.
int coco_class_id(std::string_view label);
// "motorbike" -> "motorcycle", "aeroplane" -> "airplane", "sofa" -> "couch",
// "pottedplant" -> "potted plant", "diningtable" -> "dining table", "tvmonitor" -> "tv",
// and the body model's "body" -> "person";
// any other label is returned unchanged.
std::string canonical_coco_label(std::string_view label);

// One name per line (blank trailing lines ignored), canonicalized. Throws kestrel::Error naming
// the file (and line, for an empty name in the middle).
std::vector<std::string> read_class_names(const std::string& path);

}  // namespace kestrel::detect
