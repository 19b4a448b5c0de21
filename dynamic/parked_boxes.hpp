#pragma once
// Which dynamic-class boxes hold a parked vehicle. The filter takes the object in a dynamic box
// for a mover whether it moves this instant or not (a person standing still walks off later),
// so a parked car would never reach the maps or the object database, and a ground robot would
// plan through it. A vehicle is different: one whose box the filter has judged still, frame
// after frame, for park_seconds is parked, and is judged by geometry alone from then on, like
// scenery (DynamicFilterInput boxes' `parked`). The first frame its features move against the
// ego-motion (box_moving) makes it a mover again. People and animals are never parked.
// Boxes are followed from frame to frame by IoU; pure and single-threaded.
#include <vector>

#include "core/timestamp.hpp"
#include "dynamic/dynamic_filter.hpp"

namespace kestrel::dynamic {

struct ParkedBoxOptions {
  double min_iou = 0.3;  // a box continues the previous frame's box it overlaps most
  // Still judgements spanning park_seconds, none moving, at least park_judgements of them,
  // make a parked vehicle. A robot driving past a parked car has it in depth range for a second
  // or two (ugv-loop): 1.5 s left about a second of parked boxes per car, too few keyframes for
  // the object database. A car driving at 3 m/s has nearly all its 3D-judged features off the
  // ego-motion in any frame (ugv-loop: 60 of 63), so a short proof is safe; one stopped for a
  // moment and taken as parked is still while it stands, and a mover again the frame it starts.
  double park_seconds = 0.5;
  int park_judgements = 10;
  // A box is judged from its object's own features judged in 3D (DynamicFilterResult
  // box_features): with fewer than min_features it is not judged (a far vehicle with no depth:
  // the 2D test cannot see it drive along its epipolar lines); with more than still_share of
  // them off the ego-motion it is not still.
  int min_features = 8;
  double still_share = 0.1;
  double forget_seconds = 0.5;  // a track with no box this long ends
};

class ParkedBoxTracker {
 public:
  explicit ParkedBoxTracker(ParkedBoxOptions options = {}) : options_(options) {}

  // This frame's dynamic-class boxes (`parkable`: a vehicle class) before the filter runs:
  // sets each box's `parked` from what earlier frames showed of it.
  void assign(Timestamp t, std::vector<BoxRegion>& boxes, const std::vector<bool>& parkable);
  // The filter's judgement of the same boxes.
  void observe(const DynamicFilterResult& r);

  std::size_t tracks() const { return tracks_.size(); }

 private:
  struct Track {
    BoxRegion box;
    bool parkable = false;
    Timestamp last_seen = 0;
    Timestamp still_since = 0;  // first still judgement since the last moving one
    int still = 0;              // still judgements since then
    bool parked = false;
  };
  ParkedBoxOptions options_;
  std::vector<Track> tracks_;
  std::vector<int> track_of_;  // per box of the last assign(): its track
  Timestamp now_ = 0;
};

}  // namespace kestrel::dynamic
