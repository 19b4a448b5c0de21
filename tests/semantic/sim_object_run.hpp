#pragma once
// Runs the object database and the map builder over a simulated scenario with ground-truth
// poses and ground-truth static boxes (an oracle detector), and scores the result against the
// world's objects and its static geometry. Shared by the tests and bench/semantic_bench.
#include <string>
#include <vector>

#include "maps/map_builder.hpp"
#include "semantic/object_database.hpp"

namespace kestrel::test {

struct SimObjectRunOptions {
  std::string scenario = "cafe";
  int keyframe_every = 10;  // frames
  double duration = -1.0;   // seconds; negative: the scenario's
  bool mask_movers = true;  // static pixels only (ground-truth mover masks)
  bool build_maps = true;
  std::string out_dir;  // write the outputs here when not empty
};

struct SimObjectScores {
  int truth = 0;     // world objects that were given as detections in enough keyframes
  int reported = 0;  // objects the database reports
  int matched = 0;   // reported objects matched to a distinct truth object (any label)
  int label_correct = 0;
  double recall = 0, precision = 0, class_correct = 0;
  double center_error_median = 0;  // metres, over matches
  double size_error_median = 0;    // relative, over matches and axes
  double grid_iou = 0;             // occupied cells vs the world's static geometry (1-cell slack)
  double dynamic_residue = 0;      // occupied voxels on mover paths off static geometry, fraction
  double object_ms_median = 0;     // per keyframe update
  double map_ms_median = 0;
  int keyframes = 0;
  std::vector<std::string> lines;  // one per truth object, for the report
};

SimObjectScores run_sim_objects(const SimObjectRunOptions& options);

}  // namespace kestrel::test
