#include "pipeline/sequence_object_truth.hpp"

#include <filesystem>
#include <map>

#include "core/error.hpp"
#include "sim/mover_path.hpp"

namespace kestrel::pipeline {
namespace {

bool box_usable(const io::SequenceBox& b, const ObjectTruthOptions& o) {
  return (b.x_max - b.x_min) * (b.y_max - b.y_min) >= o.min_box_pixels &&
         b.occluded <= o.max_occluded;
}

bool in_range(const ObjectTruthInput& in, const ObjectTruthOptions& o, Timestamp t,
              const Vec3& center) {
  const std::optional<Vec3> cam = in.camera_position ? in.camera_position(t) : std::nullopt;
  return cam && (center - *cam).norm() < in.depth_max - o.range_margin_m;
}

// Walkers and birds never stand still long enough to be objects; anything else may.
bool can_rest(const sim::MoverSpec& m) { return m.type != "person" && m.type != "bird"; }

}  // namespace

ObjectTruth object_truth(const ObjectTruthInput& in, const ObjectTruthOptions& options) {
  std::map<int, const io::SequenceObject*> objects;
  for (const io::SequenceObject& o : in.objects) objects[o.id] = &o;
  // A mover's final place (sim::mover_pose at the end) and its box centre there.
  struct Rest {
    sim::MoverPose pose;
    Vec3 center;
  };
  std::vector<Rest> rest;
  for (const sim::MoverSpec& m : in.movers) {
    const sim::MoverPose p = sim::mover_pose(m, in.end_s);
    rest.push_back({p, p.position + Vec3(0.0, 0.0, 0.5 * m.size.z())});
  }
  std::map<int, int> frames;          // instance -> frames that count
  std::map<int, std::string> labels;  // movers' labels, from their boxes
  for (const io::SequenceBox& b : in.boxes) {
    if (!box_usable(b, options)) continue;
    if (const auto it = objects.find(b.instance); it != objects.end()) {
      if (in_range(in, options, b.t, it->second->center)) ++frames[b.instance];
      continue;
    }
    const int m = b.instance - 1;
    if (m < 0 || m >= static_cast<int>(in.movers.size())) continue;
    const sim::MoverSpec& spec = in.movers[static_cast<std::size_t>(m)];
    if (!can_rest(spec) || b.label == "person") continue;
    const Rest& r = rest[static_cast<std::size_t>(m)];
    const sim::MoverPose now = sim::mover_pose(spec, to_seconds(b.t));
    if ((now.position - r.pose.position).norm() > options.rest_tolerance_m) continue;
    if (!in_range(in, options, b.t, r.center)) continue;
    ++frames[b.instance];
    labels[b.instance] = b.label;
  }
  ObjectTruth out;
  for (const io::SequenceObject& o : in.objects) {
    const eval::ObjectBox b{o.label, o.center, o.size, o.yaw, 0};
    out.world.push_back(b);
    if (frames[o.id] >= options.min_frames) out.visible.push_back(b);
  }
  for (std::size_t m = 0; m < in.movers.size(); ++m) {
    const sim::MoverSpec& spec = in.movers[m];
    if (!can_rest(spec)) continue;
    const int id = static_cast<int>(m) + 1;
    const std::string label = labels.count(id) ? labels[id] : spec.label;
    const eval::ObjectBox b{label, rest[m].center, spec.size, rest[m].pose.yaw, 0};
    out.world.push_back(b);
    if (frames[id] >= options.min_frames) out.visible.push_back(b);
  }
  return out;
}

eval::ObjectScores score_run_objects(const ObjectTruth& truth,
                                     const std::vector<eval::ObjectBox>& reported) {
  eval::ObjectScores s = eval::score_objects(truth.visible, reported);
  const eval::ObjectScores real = eval::score_objects(truth.world, reported);
  s.precision = real.precision;
  // The reports that match nothing in the world are the false ones; list those, not the
  // objects the visibility rule left out.
  std::erase_if(s.lines, [](const std::string& l) { return l.rfind("extra", 0) == 0; });
  for (const std::string& l : real.lines)
    if (l.rfind("extra", 0) == 0) s.lines.push_back(l);
  return s;
}

std::optional<ObjectTruth> read_object_truth(const std::string& dir, const Trajectory& T_w_body,
                                             const SE3& T_body_camera,
                                             const ObjectTruthOptions& options) {
  namespace fs = std::filesystem;
  const std::string objects = dir + "/objects.json", boxes = dir + "/boxes.csv",
                    scenario = dir + "/scenario.yaml";
  if (T_w_body.empty() || !fs::exists(objects) || !fs::exists(boxes) || !fs::exists(scenario)) {
    return std::nullopt;
  }
  ObjectTruthInput in;
  in.objects = io::read_objects(objects);
  in.boxes = io::read_boxes(boxes);
  const sim::Scenario s = sim::load_scenario(scenario);
  in.movers = s.movers;
  in.depth_max = s.sensor.depth_max;
  in.end_s = T_w_body.stamps.back();
  in.camera_position = [&T_w_body, &T_body_camera](Timestamp t) -> std::optional<Vec3> {
    const auto i = nearest_pose(T_w_body, to_seconds(t), 0.02);
    if (!i) return std::nullopt;
    return (T_w_body.poses[*i] * T_body_camera).translation();
  };
  return object_truth(in, options);
}

}  // namespace kestrel::pipeline
