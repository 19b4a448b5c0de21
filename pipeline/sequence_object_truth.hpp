#pragma once
// The ground-truth objects a run over a simulated sequence could have put in its object
// database, so `kestrel run` can score its own objects.json against the world (issue 6's
// object figures with the SLAM poses and the run's detector in the loop, not only with the
// truth's; pipeline/sim_object_run has those).
//
// A static object counts once its box was large and unoccluded enough, and the object within
// the sensor's range, in enough frames: the rule sim_object_run applies to its keyframes,
// on boxes.csv. A mover that is not a walker or a bird (a pushed chair, a chair turning in
// place, a parked car) counts too, where it rests at the end of the sequence, by the same rule
// over the frames it stood there: the database is meant to hold it there (it "returns where it
// stops"), and the world's objects.json lists only the static objects.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/se3.hpp"
#include "core/timestamp.hpp"
#include "core/trajectory.hpp"
#include "eval/object_metrics.hpp"
#include "io/kestrel_sequence.hpp"
#include "sim/scenario.hpp"

namespace kestrel::pipeline {

struct ObjectTruthOptions {
  double min_box_pixels = 400.0;  // box area
  double max_occluded = 0.5;      // boxes.csv's occluded fraction
  double range_margin_m = 0.5;    // within the sensor's depth_max less this
  int min_frames = 30;            // about sim_object_run's 3 keyframes, 10 frames apart
  double rest_tolerance_m = 0.1;  // a mover this near its final place stands there
};

struct ObjectTruthInput {
  std::vector<io::SequenceObject> objects;  // the world's static objects (objects.json)
  std::vector<io::SequenceBox> boxes;       // boxes.csv
  std::vector<sim::MoverSpec> movers;       // mover i has instance id i + 1
  double depth_max = 8.0;                   // metres
  double end_s = 0.0;                       // the sequence's last stamp
  // The camera's position at a frame stamp; nothing where the truth has none.
  std::function<std::optional<Vec3>(Timestamp)> camera_position;
};

// What a run is scored against: recall over what it could see, precision over everything in
// the world (an object seen well in fewer frames than the rule asks is still no false report).
struct ObjectTruth {
  std::vector<eval::ObjectBox> visible;  // by the rule above
  std::vector<eval::ObjectBox> world;    // every static object, every mover where it rests
};

ObjectTruth object_truth(const ObjectTruthInput& in, const ObjectTruthOptions& options = {});

// Recall, matches and their errors against truth.visible; precision against truth.world.
eval::ObjectScores score_run_objects(const ObjectTruth& truth,
                                     const std::vector<eval::ObjectBox>& reported);

// The same from a Kestrel sequence folder written by `kestrel sim` (objects.json, boxes.csv,
// scenario.yaml) and its ground-truth body trajectory; nothing when the folder lacks one of the
// three (a recorded sequence has no world to score against). Throws kestrel::Error, naming the
// file, for one that cannot be read.
std::optional<ObjectTruth> read_object_truth(const std::string& dir, const Trajectory& T_w_body,
                                             const SE3& T_body_camera,
                                             const ObjectTruthOptions& options = {});

}  // namespace kestrel::pipeline
