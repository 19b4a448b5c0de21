#pragma once
// Runs the object database and the map builder over a simulated scenario with ground-truth
// poses and ground-truth static boxes (an oracle detector), and scores the result against the
// world's objects and its static geometry with eval/'s metrics. Shared by the semantic tests
// and `kestrel bench`: it isolates the object and map stages from tracking error.
#include <functional>
#include <string>
#include <vector>

#include "maps/map_builder.hpp"
#include "semantic/object_database.hpp"
#include "sim/simulator.hpp"

namespace kestrel::pipeline {

struct SimObjectRunOptions {
  std::string scenario = "cafe";
  int keyframe_every = 10;  // frames
  double duration = -1.0;   // seconds; negative: the scenario's
  bool mask_movers = true;  // static pixels only (ground-truth mover masks)
  bool build_maps = true;
  std::string out_dir;  // write the outputs here when not empty
  // A mover standing still (a chair not yet pushed) is a detection of its label like any
  // object, and its pixels are masked only while it moves: what a detector and the dynamic
  // filter's moving flag give. Off: movers are always masked and never detected. People are
  // always masked.
  bool detect_still_movers = false;
  // With detect_still_movers: the truth tells which of those movers moves now (its box is a
  // moving box, its pixels masked). Off: a moving chair is a chair like any other and its pixels
  // stay in, as in a live run, where the detector calls it a chair whether it moves or not and
  // the dynamic filter cannot see a push at 0.3 m/s from 7 m (under a pixel a frame); the
  // object database must notice the move itself.
  bool moving_flags = true;
  // A ground robot's (trajectory kind ugv) body radius: its disc at each keyframe is free in the
  // grid (footprint clearing), as on the agent. 0: none.
  double robot_radius = 0.25;                         // metres; also the planner's
  std::function<void(sim::Scenario&)> edit_scenario;  // applied after loading, before the run
  // Called after each keyframe's update, with the keyframe's true time.
  std::function<void(const sim::Simulator&, double t, const semantic::ObjectDatabase&)> on_keyframe;
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
  // A* on the built grid (nav::plan_path, robot radius 0.25 m) between the two keyframe places
  // farthest apart that the inflated grid holds free: found, its length, whether no cell of it
  // lies on the world's static geometry, and why not when not found. Then each truth object's
  // centre as the goal: refused (goal blocked), as a goal inside an obstacle must be.
  bool path_found = false;
  double path_length = 0;
  bool path_clear = false;
  std::string path_message;
  int object_goals = 0;
  int object_goals_refused = 0;
  std::string object_goal_message;  // the first refusal's, for the report
  double object_ms_median = 0;      // per keyframe update
  double map_ms_median = 0;
  int keyframes = 0;
  std::vector<std::string> lines;  // one per truth object, for the report
};

SimObjectScores run_sim_objects(const SimObjectRunOptions& options);

}  // namespace kestrel::pipeline
