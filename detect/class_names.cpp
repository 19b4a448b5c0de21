#include "detect/class_names.hpp"

#include <algorithm>
#include <array>
#include <fstream>
#include <utility>

#include "core/error.hpp"

namespace kestrel::detect {

const std::vector<std::string>& coco_class_names() {
  static const std::vector<std::string> kNames = {"person",        "bicycle",      "car",
                                                  "motorcycle",    "airplane",     "bus",
                                                  "train",         "truck",        "boat",
                                                  "traffic light", "fire hydrant", "stop sign",
                                                  "parking meter", "bench",        "bird",
                                                  "cat",           "dog",          "horse",
                                                  "sheep",         "cow",          "elephant",
                                                  "bear",          "zebra",        "giraffe",
                                                  "backpack",      "umbrella",     "handbag",
                                                  "tie",           "suitcase",     "frisbee",
                                                  "skis",          "snowboard",    "sports ball",
                                                  "kite",          "baseball bat", "baseball glove",
                                                  "skateboard",    "surfboard",    "tennis racket",
                                                  "bottle",        "wine glass",   "cup",
                                                  "fork",          "knife",        "spoon",
                                                  "bowl",          "banana",       "apple",
                                                  "sandwich",      "orange",       "broccoli",
                                                  "carrot",        "hot dog",      "pizza",
                                                  "donut",         "cake",         "chair",
                                                  "couch",         "potted plant", "bed",
                                                  "dining table",  "toilet",       "tv",
                                                  "laptop",        "mouse",        "remote",
                                                  "keyboard",      "cell phone",   "microwave",
                                                  "oven",          "toaster",      "sink",
                                                  "refrigerator",  "book",         "clock",
                                                  "vase",          "scissors",     "teddy bear",
                                                  "hair drier",    "toothbrush"};
  return kNames;
}

std::string canonical_coco_label(std::string_view label) {
  // Darknet's coco.names keeps six VOC spellings; the person-only body model calls its one
  // class "body".
  static const std::array<std::pair<std::string_view, std::string_view>, 7> kAliases = {{
      {"body", "person"},
      {"motorbike", "motorcycle"},
      {"aeroplane", "airplane"},
      {"sofa", "couch"},
      {"pottedplant", "potted plant"},
      {"diningtable", "dining table"},
      {"tvmonitor", "tv"},
  }};
  for (const auto& [from, to] : kAliases) {
    if (label == from) return std::string(to);
  }
  return std::string(label);
}

int coco_class_id(std::string_view label) {
  const std::string canonical = canonical_coco_label(label);
  const auto& names = coco_class_names();
  const auto it = std::find(names.begin(), names.end(), canonical);
  return it == names.end() ? -1 : static_cast<int>(it - names.begin());
}

std::vector<std::string> read_class_names(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error::at(path, 0, "", "cannot open class-names file");
  std::vector<std::string> names;
  std::vector<int> blank_lines;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    // Names hold spaces ("traffic light"), so only the line ends are trimmed.
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) {
      line.pop_back();
    }
    if (line.empty()) {
      blank_lines.push_back(line_no);
      continue;
    }
    // A blank line followed by a name would shift every later class id by one.
    if (!blank_lines.empty()) {
      throw Error::at(path, blank_lines.front(), "name", "empty class name before the last one");
    }
    names.push_back(canonical_coco_label(line));
  }
  if (names.empty()) throw Error::at(path, 0, "", "no class names in file");
  return names;
}

}  // namespace kestrel::detect
