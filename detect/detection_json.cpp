#include "detect/detection_json.hpp"

#include <fstream>
#include <nlohmann/json.hpp>

#include "core/error.hpp"

namespace kestrel::detect {

std::string detections_to_json(const std::vector<LabelledDetectionSet>& sets) {
  nlohmann::json all = nlohmann::json::array();
  for (const LabelledDetectionSet& s : sets) {
    nlohmann::json boxes = nlohmann::json::array();
    for (const Detection& d : s.set.boxes) {
      boxes.push_back({{"label", d.label},
                       {"class_id", d.class_id},
                       {"score", d.score},
                       {"x_min", d.x_min},
                       {"y_min", d.y_min},
                       {"x_max", d.x_max},
                       {"y_max", d.y_max}});
    }
    all.push_back({{"source", s.source},
                   {"t", to_seconds(s.set.t)},
                   {"latency_ms", s.set.latency_ms},
                   {"boxes", std::move(boxes)}});
  }
  return all.dump(2) + "\n";
}

void write_detections_json(const std::string& path, const std::vector<LabelledDetectionSet>& sets) {
  std::ofstream out(path);
  if (!out) throw Error::at(path, 0, "", "cannot open for writing");
  out << detections_to_json(sets);
  out.flush();
  if (!out) throw Error::at(path, 0, "", "write failed");
}

}  // namespace kestrel::detect
