#pragma once
// The sparse map: map points and keyframes as plain data (ORB-SLAM's model without its
// threads). Whoever owns a Map serializes access to it; pipeline/ decides who that is.
#include <cstdint>
#include <map>
#include <optional>
#include <unordered_map>
#include <vector>

#include "core/imu.hpp"
#include "core/se3.hpp"
#include "core/timestamp.hpp"
#include "mapping/flat_keyframe_map.hpp"
#include "tracking/frame_features.hpp"

namespace kestrel::mapping {

using tracking::FrameFeatures;
using tracking::OrbDescriptor;
using PointId = std::int64_t;
inline constexpr PointId kNoPoint = -1;

struct MapPoint {
  PointId id = kNoPoint;
  Vec3 p_w = Vec3::Zero();
  OrbDescriptor descriptor;      // the most representative of its observations
  Vec3 normal = Vec3::UnitZ();   // mean viewing direction (camera centre to point), unit
  FlatKeyframeMap observations;  // keyframe -> feature index in that keyframe
  KeyframeId first_keyframe = -1;
  // Culling statistics: how often the point was predicted in view vs. actually matched.
  int visible = 1;
  int found = 1;
  // Distances over which ORB's scale pyramid can re-detect the point.
  double min_distance = 0.0;
  double max_distance = 0.0;

  double found_ratio() const { return visible > 0 ? static_cast<double>(found) / visible : 0.0; }
  // Pyramid level at which the point should appear from `distance` metres away.
  int predict_level(double distance, double scale_factor, int levels) const;
};

// The gyro's word on how a keyframe's camera turned since an earlier keyframe: R_c_from maps
// directions of keyframe `from`'s camera into this one's (bias-corrected integration), good to
// sigma_rad per axis. Over the seconds between keyframes the gyro is far better than vision at
// rotation; local BA holds the keyframes to it, so a map cannot tilt away from the IMU.
// Session-only: not written to map.bin (a loaded map's keyframes have none).
struct GyroLink {
  KeyframeId from = -1;
  Mat3 R_c_from = Mat3::Identity();
  double dt_s = 0.0;
  double sigma_rad = 0.0;
  // The whole pre-integration over the same interval (velocity and position as well), with
  // what it needs to become an inertial factor in local BA: the world's gravity and the body
  // (IMU) to camera transform. Nothing where the IMU was not integrated, or once a culled
  // keyframe's links are composed (pre-integrations do not compose through their bias
  // Jacobians).
  std::optional<PreintegratedImu> imu;
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);
  SE3 T_body_camera;
};

struct Keyframe {
  KeyframeId id = -1;
  Timestamp t = 0;
  SE3 T_w_c;
  FrameFeatures features;
  std::vector<PointId> point_of_feature;  // kNoPoint where a feature has no map point
  FlatKeyframeMap connections;            // covisibility: shared map points per keyframe
  std::optional<GyroLink> gyro;           // to the keyframe before it, when there is an IMU
  // Body (IMU) velocity in the world when the keyframe was taken: the IMU's prediction, then
  // visual-inertial local BA's estimate. Session-only, like the gyro link.
  std::optional<Vec3> v_w;

  SE3 T_c_w() const { return T_w_c.inverse(); }
};

struct CullingOptions {
  double min_found_ratio = 0.25;  // matched / predicted-in-view
  int min_observations = 3;       // keyframes that must see a point two keyframes after its birth
};

class Map {
 public:
  Map() = default;
  // A copy indexes its own keyframes (keyframe_at_ holds addresses into keyframes_).
  Map(const Map& other);
  Map& operator=(const Map& other);
  Map(Map&&) noexcept = default;  // a moved std::map keeps its nodes where they are
  Map& operator=(Map&&) noexcept = default;

  KeyframeId add_keyframe(Timestamp t, const SE3& T_w_c, FrameFeatures features);
  // A point seen by `feature` of keyframe `kf`.
  PointId add_point(const Vec3& p_w, KeyframeId kf, int feature);
  void add_observation(PointId p, KeyframeId kf, int feature);
  void erase_observation(PointId p, KeyframeId kf);
  void erase_point(PointId p);
  // Recomputes descriptor, normal and scale-invariance distances from the observations.
  void update_point(PointId p);
  // The two halves: the descriptor depends only on which keyframes observe the point, and
  // costs the square of their number, so it is chosen among the newest kDescriptorViews (a
  // point a revisiting robot sees from 300 keyframes: 1024 Hamming distances, not 90000);
  // normal and distances follow its position, which BA moves.
  void update_point_descriptor(PointId p);
  static constexpr std::size_t kDescriptorViews = 32;  // the newest views it chooses from
  void update_point_geometry(PointId p);

  // Creates map points from the depth of a keyframe's features that have none yet, nearest
  // first, at most max_new. Returns how many.
  int create_points_from_depth(KeyframeId kf, int max_new, double max_depth);
  // ORB-SLAM's recent-point culling; returns the number of points removed.
  int cull_points(KeyframeId current, const CullingOptions& options = {});
  // Recomputes the covisibility weights of `kf` (and the reverse edges).
  void update_connections(KeyframeId kf, int min_shared = 15);
  // Map points of kf seen by at least min_observations keyframes (ORB-SLAM's keyframe test).
  int tracked_points(KeyframeId kf, int min_observations) const;
  // ORB-SLAM's keyframe-culling test: of kf's points observed closer than max_depth, the
  // fraction that at least `observers` other keyframes see at the same or a finer pyramid level
  // (one level of slack). 0 when kf has no such point.
  double redundancy(KeyframeId kf, double max_depth, int observers = 3) const;
  // redundancy(kf, max_depth, observers) > fraction, found walking only as many points as it
  // takes to know.
  bool is_redundant(KeyframeId kf, double max_depth, int observers, double fraction) const;
  // Removes a keyframe: its observations (a point it alone saw goes with it) and its
  // covisibility edges (a neighbour left with no link gets its strongest one back; the weights
  // between the others do not change). A gyro link to it is carried
  // through to the keyframe it linked to (rotations composed, variances added).
  void erase_keyframe(KeyframeId kf);
  // Up to n keyframes sharing the most points with kf, best first.
  std::vector<KeyframeId> covisible(KeyframeId kf, int n) const;

  Keyframe* keyframe(KeyframeId id);
  const Keyframe* keyframe(KeyframeId id) const;
  MapPoint* point(PointId id);
  const MapPoint* point(PointId id) const;
  const std::map<KeyframeId, Keyframe>& keyframes() const { return keyframes_; }
  const std::unordered_map<PointId, MapPoint>& points() const { return points_; }
  std::size_t num_points() const { return points_.size(); }
  std::size_t num_keyframes() const { return keyframes_.size(); }
  KeyframeId last_keyframe_id() const {
    return keyframes_.empty() ? -1 : keyframes_.rbegin()->first;
  }

  // Replaces the contents with saved keyframes and points (map_io), keeping their ids; new
  // ids continue past the largest. Point <-> keyframe links are taken as given (map_io checks
  // them). No point counts as recent, so none is culled as a newborn.
  void restore(std::map<KeyframeId, Keyframe> keyframes,
               std::unordered_map<PointId, MapPoint> points);

 private:
  // The keyframe-culling test's parts: the map point of feature i of kf when its depth is
  // within max_depth (else nullptr); p is seen by `observers` keyframes other than kid at a
  // pyramid level <= level + 1.
  const MapPoint* close_point(const Keyframe& kf, std::size_t i, double max_depth) const;
  bool seen_by_others(const MapPoint& p, KeyframeId kid, int level, int observers) const;

  // keyframe_at_[id]: keyframe id's node in keyframes_ (a std::map's nodes stay put), nullptr
  // where none or not indexed. Every view a revisited place's point holds is looked up by id:
  // keyframe culling walks them, and a tree's descent per view was half of its cost
  // (bench_mapping's culling test). Ids are
  // dense as the map hands them out; a loaded map's ids may be sparse, and one far beyond the
  // keyframe count is left to the tree.
  void index_keyframe(KeyframeId id, Keyframe* kf);
  void reindex_keyframes();
  const Keyframe* find_keyframe(KeyframeId id) const;

  std::map<KeyframeId, Keyframe> keyframes_;
  std::vector<Keyframe*> keyframe_at_;
  std::unordered_map<PointId, MapPoint> points_;
  std::vector<PointId> recent_points_;  // candidates for culling
  KeyframeId next_keyframe_ = 0;
  PointId next_point_ = 0;
};

}  // namespace kestrel::mapping
