#pragma once
// The database of static objects (DESIGN.md semantic/), updated once per keyframe from the
// mapping thread: the depth inside every static-class detection box is split into Euclidean
// clusters; the nearest cluster whose image footprint overlaps the box (IoU) and whose depth is
// consistent becomes a measurement; measurements of one label close together fuse into one
// object. Points stay in their keyframe's camera frame, so a corrected keyframe pose
// (reanchor) moves the objects with the map. No threads here.
#include <cstdint>
#include <map>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Core>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/se3.hpp"
#include "core/timestamp.hpp"
#include "detect/detection.hpp"
#include "io/kestrel_sequence.hpp"
#include "semantic/object_geometry.hpp"

namespace kestrel::semantic {

struct ObjectDatabaseOptions {
  int pixel_stride = 2;             // depth pixels sampled inside a box
  double min_depth = 0.3;           // metres
  double max_depth = 8.0;           // metres
  double depth_noise_z2 = 0.003;    // the sensor's depth sigma = this x depth^2 (D455-like)
  int smooth_radius = 2;            // depth averaged over (2r+1)^2 neighbours on one surface
  float cluster_tolerance = 0.06f;  // metres between surfaces of one cluster
  int min_cluster_points = 30;
  double min_iou = 0.5;        // cluster footprint vs detection box
  double iou_tie = 0.15;       // footprints this close in IoU: the nearer cluster wins
  double max_depth_rms = 0.6;  // metres, spread of a cluster's depth about its median
  // A box partly overlapped by others takes only clusters seen where none overlaps it (its own
  // region), when that region holds this share of the box and this many surface points; a
  // cluster needs min_own_region_points there. Cafe (truth poses and boxes, kestrel bench
  // --only objects): a chair tucked behind its table took the table's front for itself, and the
  // chair in front of it swelled to 0.79 x 0.65 m with the fused result; centre error median
  // 0.116 -> 0.098 m, size error 0.064 -> 0.017; market 0.071 -> 0.043 m (one of its dining
  // tables 0.235 -> 0.020 m off).
  double min_own_region_share = 0.1;
  int min_own_region_surface = 10;
  int min_own_region_points = 3;
  // Such a box that found no cluster is measured from the cluster in its own region and the
  // parts of others at about its depth: what hides an object's middle cuts it in two (a chair
  // behind its table: backrest above, legs below). With max_length_over_prior, cafe's chair
  // tucked behind its table, missed until then, is found: recall 5/6 -> 6/6, centre error
  // median 0.098 m (kestrel bench --only objects).
  bool join_parts = true;
  // A measurement longer than this x its class's typical length (size_prior.hpp) is several
  // objects taken for one, and dropped.
  double max_length_over_prior = 2.0;
  double depth_extent_factor = 0.75;     // keep cluster points within this x box width (metres)
  double min_depth_extent = 0.25;        // ... or this, of the cluster's median depth
  bool extend_past_depth_extent = true;  // ... unless no other box holds the pixel
  double min_box_pixels = 400;           // smaller boxes are too far or too cut to measure
  double border_margin = -1.0;           // pixels; >= 0: boxes reaching the border are not measured
  double point_voxel = 0.03;             // metres, an observation's points are thinned to this
  int max_points_per_observation = 600;
  int max_observations_kept = 60;  // per object, the latest ones
  double floor_margin = 0.04;      // metres above the floor estimate that count as floor
  double floor_noise = 0.006;      // plus this times depth^2 (depth noise grows with z^2)
  double associate_factor = 0.75;  // same label, centres closer than this x the larger size
  double merge_factor = 0.75;      // same rule between two objects
  // Same label and sharing this fraction of occupied voxels: one object seen in parts (a car
  // cut by the image border, seen end-on then side-on), whatever its centres say.
  double overlap_voxel = 0.15;  // metres
  double min_overlap = 0.3;
  int min_observations = 3;  // fewer: a mislabel or a passing glimpse, not reported
  // A measurement whose surface goes on past an edge of its box (not the image border) on this
  // share of that edge is a part of something larger than the box's object: a stall in front of
  // the table it hides, whose box it fills. An object needs min_whole_observations views that
  // are not such parts to be reported; until then it is held and fused, tentative.
  double min_edge_continuation = 0.5;
  int min_whole_observations = 1;
  double moving_iou = 0.3;  // a moving box this close to an object's projection removes it
  // An object no one reports as moving can still be seen to move: a chair pushed at 0.3 m/s 7 m
  // away moves under a pixel a frame, which the dynamic filter cannot tell from noise, and the
  // detector calls it a chair either way. Its measurements then walk away from where it stood:
  // move_streak of them in a row, each farther than move_factor x its length (at least
  // min_move) from the object's centre, the last move_travel or more farther than the first,
  // within move_window. Such measurements are held out of the object meanwhile (fused after all
  // if the streak proves no move). A moving object leaves the report and follows its
  // measurements; it returns once they stay within still_factor x that distance for
  // still_seconds and still_views views. Static
  // objects' measurements stay nearer (cafe, market, ugv-loop with truth poses and boxes: three
  // in a row at most 0.08 m from a chair's centre, 0.29 m from a 1.2 m table's, 1.74 m from a
  // 4.2 m car's seen end-on, an offset that does not travel).
  double min_move = 0.25;     // metres
  double move_factor = 0.5;   // of its class's typical length (its own longer side if none)
  int move_streak = 3;        // measurements
  double move_travel = 0.1;   // metres
  double move_window = 2.0;   // seconds a streak has to prove a move
  double still_factor = 0.5;  // of the move distance
  double still_seconds = 1.0;
  int still_views = 3;
  double lost_mover_seconds = 4.0;  // a moving object not measured this long is dropped
  // An object wholly in view, within range less absent_range_margin, with no box of its label
  // on it (IoU moving_iou) and its surfaces not there (under min_support_share of the depth
  // samples in its image box fall within absent_margin of it; floor skipped; no return counts,
  // since an object in range would give one) in absent_keyframes keyframes in a row is gone.
  // A view hidden by something nearer (max_hidden_share of the samples) tells nothing. Both
  // signs are needed: a detector missing an object still sees its surfaces, and a black or
  // shiny object that gives no depth is still detected.
  double absent_range_margin = 0.5;  // metres
  double absent_margin = 0.1;        // metres, plus twice the depth noise
  double min_support_share = 0.15;
  double max_hidden_share = 0.5;
  int min_absent_samples = 20;
  int absent_keyframes = 3;
  // Sides no view could see are completed to their class's smallest size (size_prior.hpp).
  bool size_priors = true;
};

struct ObjectKeyframe {
  std::int64_t keyframe_id = 0;
  SE3 T_w_c;
  Timestamp stamp = 0;
  const Image* depth = nullptr;  // 16-bit
  double depth_scale = 5000.0;
  PinholeCamera camera;
  // Per pixel (row-major): non-zero = static. Null: all static. Mover pixels never join a cluster.
  const std::vector<std::uint8_t>* static_mask = nullptr;
  std::vector<detect::Detection> static_boxes;  // static classes (chair, tv, ...)
  std::vector<detect::Detection> moving_boxes;  // boxes the dynamic filter saw moving
};

struct SemanticObject {
  int id = 0;
  std::string label;
  UprightBox box;
  int observations = 0;
  int whole_observations = 0;  // of them, views whose surface ends within the box
  double score_sum = 0.0;
  Timestamp first_seen = 0;
  Timestamp last_seen = 0;
  bool moving = false;  // seen moving and not yet still again; not reported meanwhile
  double confidence() const;
};

struct ObjectUpdateStats {
  int boxes = 0;     // static boxes considered
  int measured = 0;  // boxes that gave a cluster
  int created = 0;
  int merged = 0;
  int removed_moving = 0;
  int started_moving = 0;  // objects whose measurements were seen walking away
  int stopped = 0;         // moving objects seen still again, back in the report
  int removed_absent = 0;  // objects no longer where they stood
  int lost_moving = 0;     // moving objects no longer measured
};

class ObjectDatabase {
 public:
  explicit ObjectDatabase(const ObjectDatabaseOptions& options = {});

  ObjectUpdateStats update(const ObjectKeyframe& kf);
  // A keyframe's pose changed (loop closure, BA): objects seen from it move with it.
  void reanchor(std::int64_t keyframe_id, const SE3& T_w_c);

  // Objects seen often enough to report (options.min_observations).
  std::vector<SemanticObject> objects() const;
  // Every object held, rare ones included.
  std::vector<SemanticObject> all_objects() const;
  std::vector<io::SequenceObject> to_sequence_objects() const;
  // DIR/objects.json (DESIGN.md objects contract).
  void write_outputs(const std::string& dir) const;

  double floor_height() const { return floor_z_; }
  bool has_floor() const { return floor_samples_ > 0; }

 private:
  struct Observation {
    std::int64_t keyframe_id = 0;
    std::vector<Eigen::Vector3f> points_c;  // camera frame of that keyframe
    // Unit direction past the image's left or right border that cut this view (camera frame,
    // so a corrected keyframe pose turns it too); zero when the view was not cut.
    Vec3 cut_c = Vec3::Zero();
  };
  // A view with what fusing it adds to its object's counts.
  struct HeldView {
    Observation view;
    float score = 0.0f;
    double depth = 0.0;
    bool cut = false;
    Timestamp stamp = 0;
    std::string label;  // as the detector named it this time
  };
  struct Entry {
    SemanticObject object;
    std::vector<Observation> views;
    double mean_depth = 0.0;                   // of its measurements, for the floor cut
    std::unordered_set<std::uint64_t> voxels;  // world cells (overlap_voxel) its points occupy
    int displaced = 0;                         // measurements in a row far from its centre
    Vec2 displaced_last = Vec2::Zero();        // the latest of them
    Timestamp displaced_since = 0;
    double displaced_away = 0.0;  // the first one's distance from the centre
    std::vector<HeldView> held;   // the streak's views, fused if it proves no move
    // Detector score summed per label its views came with: the object takes the highest (a
    // parked pickup is a car in one view, a truck in the next).
    std::vector<std::pair<std::string, double>> votes;
    Vec2 still_at = Vec2::Zero();  // while moving: where its latest stop began
    Timestamp still_since = 0;
    int absent = 0;  // keyframes in a row that showed its place without it
  };
  enum class Sighting { kSeen, kAbsent, kUnknown };
  struct Measurement {
    std::string label;
    float score = 0.0f;
    std::vector<Eigen::Vector3f> points_c;
    std::vector<Eigen::Vector3f> points_w;
    UprightBox box;
    double depth = 0.0;  // median camera depth of its cluster
    bool cut = false;    // its surface goes on past the box: a part of something larger
    Vec2 cut_towards = Vec2::Zero();  // world direction past the one side border it touches
  };

  void update_floor(const ObjectKeyframe& kf);
  // Height above the floor estimate below which a point seen at `depth` counts as floor.
  double floor_cut(double depth) const {
    return options_.floor_margin + options_.floor_noise * depth * depth;
  }
  // One measurement per static box that a depth cluster explains; a cluster serves one box.
  std::vector<Measurement> measure_all(const ObjectKeyframe& kf) const;
  void refit(Entry& e) const;
  void fuse(Entry& e, HeldView&& v) const;
  // What a keyframe shows where an object stands (its box, its surfaces, or neither).
  Sighting look_for(const Entry& e, const ObjectKeyframe& kf) const;
  // What a whole view measured at `at` does to an entry: fuse into it, wait (held out while
  // measurements walk away, until they prove a move or come back), or restart it from here (it
  // moved); updates the entry's move state.
  enum class MotionStep { kFuse, kHold, kRestart };
  MotionStep track_motion(Entry& e, const Vec2& at, Timestamp stamp,
                          ObjectUpdateStats& stats) const;
  int merge_duplicates();
  std::vector<Eigen::Vector3f> world_points(const Entry& e) const;
  std::unordered_set<std::uint64_t> voxels_of(const std::vector<Eigen::Vector3f>& pts_w) const;

  ObjectDatabaseOptions options_;
  std::map<int, Entry> entries_;
  std::unordered_map<std::int64_t, SE3> keyframe_poses_;
  int next_id_ = 1;
  double floor_z_ = 0.0;
  int floor_samples_ = 0;
};

}  // namespace kestrel::semantic
