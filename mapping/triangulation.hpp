#pragma once
// New map points from two views (ORB-SLAM's CreateNewMapPoints), for the features depth cannot
// place: beyond the sensor's range (a drone hovering 8 m over the ground, the far walls of a
// hall) or on holes. A new keyframe's unmatched features are matched, along their epipolar lines,
// to the unmatched features of its covisible keyframes, and a pair with enough parallax whose
// triangulated point reprojects into both becomes a map point. Points from depth come first
// (Map::create_points_from_depth); this fills in what depth leaves out. Culling (Map::cull_points)
// removes the ones no third keyframe confirms.
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "core/camera.hpp"
#include "mapping/map.hpp"

namespace kestrel::mapping {

struct TriangulationOptions {
  int neighbours = 6;           // covisible keyframes searched, most shared points first
  int max_hamming = 50;         // descriptor distance of a match (ORB's TH_LOW)
  double ratio = 0.8;           // best / second-best distance along the epipolar band
  double epipolar_chi2 = 3.84;  // distance to the epipolar line, in the level's sigma
  double reprojection_chi2 = 5.991;
  double min_parallax_deg = 1.0;     // between the two rays at the point
  double min_baseline_ratio = 0.01;  // baseline / median scene depth of the keyframe
  double max_distance = 80.0;        // metres from the keyframe: farther is no better than a ray
  bool only_without_depth = true;    // features with a depth reading get their point from it
  // Features on a depth step (tracking::FrameFeatures::on_depth_step) are not triangulated.
  bool skip_depth_steps = true;
  // With a range sensor's depth, the features left to triangulate have no reading at or around
  // them: what they see lies beyond the sensor's range. A point triangulated nearer than this
  // share of the keyframe's farthest readings (their 99th percentile: about the sensor's range
  // when the scene reaches beyond it; in a closed room the far wall, and then a near point in a
  // depth hole, glass or black paint, is refused too) contradicts the sensor: it comes from a wrong
  // match along the epipolar line, kept because its error pushed a far point's small parallax over
  // min_parallax_deg. Measured on cafe seed 3 against the room's walls (ray cast from the true
  // pose): without the check points floated at 5-8 m in front of a wall 11 m away, and some 0.1-0.6
  // m in front of the camera; with it, 85% of the points lie within 10% of the true range, and the
  // 60 s run's APE without loop closure is 4.5 mm (without triangulation, 12.6 mm). 0: no check.
  double min_depth_past_readings = 0.9;
  // Keyframes that must see the point (a match near its projection) before it is created: two
  // are the pair; a third rules out most movers that happen to fit one epipolar line.
  int min_views = 3;
};

// The three steps apart, so that the matching (milliseconds per keyframe) runs on the
// local-mapping thread while the tracking thread, which owns the map, goes on: gather copies
// what the search reads, solve touches no map, apply writes the points back.

// One keyframe as the search sees it, copied out of the map.
struct TriangulationView {
  KeyframeId id = -1;
  SE3 T_w_c;
  tracking::FrameFeatures features;
  std::vector<std::uint8_t> has_point;  // per feature: observes a map point already
};

struct TriangulationProblem {
  TriangulationView current;                  // the new keyframe
  std::vector<TriangulationView> neighbours;  // covisible, most shared points first
  double median_depth = 0.0;                  // of the new keyframe's points and readings
};

// A point to create: seen by views[0] (the new keyframe's feature), views[1] (its pair) and the
// confirming views after them; (keyframe, feature) each.
struct NewMapPoint {
  Vec3 p_w;
  std::vector<std::pair<KeyframeId, int>> views;
};

// What the search for keyframe `kf` needs; nothing when the map has no such keyframe.
std::optional<TriangulationProblem> gather_triangulation(const Map& map, KeyframeId kf,
                                                         const TriangulationOptions& options = {});
std::vector<NewMapPoint> solve_triangulation(const TriangulationProblem& problem,
                                             const PinholeCamera& camera,
                                             const TriangulationOptions& options = {});
// Creates the points whose first two views still exist with their features free (the map may
// have changed since gather: a keyframe culled, a feature matched); a confirming view that no
// longer qualifies is left out. Returns the number created.
int apply_triangulation(Map& map, const std::vector<NewMapPoint>& points);

// The three in one. Returns the number of points created for keyframe `kf`.
int triangulate_new_points(Map& map, KeyframeId kf, const PinholeCamera& camera,
                           const TriangulationOptions& options = {});

}  // namespace kestrel::mapping
