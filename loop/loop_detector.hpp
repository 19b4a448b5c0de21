#pragma once
// Loop detection and relocalisation: place recognition (vocabulary + keyframe database +
// temporal consistency) followed by geometric verification (descriptor matching guided by the
// vocabulary's direct index, then PnP-RANSAC against the candidate's depth points).
// A plain class: the loop-closing thread feeds it one keyframe at a time.
#include <cstdint>
#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "core/camera.hpp"
#include "core/se3.hpp"
#include "loop/keyframe_database.hpp"
#include "loop/vocabulary.hpp"

namespace kestrel::loop {

// What the detector needs of a keyframe (build it from mapping::Keyframe: features.keypoints[i].un,
// features.descriptors, features.points_c where features.has_depth(i), covisible keyframes).
struct PlaceView {
  KeyframeId id = -1;
  std::vector<OrbDescriptor> descriptors;
  std::vector<Vec2> keypoints_un;       // undistorted pixels, one per descriptor
  std::vector<Vec3> points_c;           // camera-frame point per feature
  std::vector<std::uint8_t> has_point;  // != 0 where points_c is valid (depth seen)
  std::vector<KeyframeId> neighbours;   // covisible keyframes (excluded, and the normaliser)
};

struct LoopDetectorOptions {
  KeyframeDatabaseOptions database;
  int consistency = 3;        // consecutive queries confirming a candidate group
  int recent_exclusion = 15;  // keyframes with id > query id - this are never loop candidates
  int direct_depth = 2;       // vocabulary level of the direct index for guided matching
  int max_hamming = 50;
  double ratio = 0.8;  // best / second-best Hamming distance
  double ransac_reprojection_px = 3.0;
  int ransac_iterations = 200;
  int min_inliers = 30;
};

struct LoopMatch {
  KeyframeId query = -1;
  KeyframeId match = -1;
  SE3 T_match_query;  // pose of the query camera in the matched keyframe's camera frame
  int matches = 0;    // descriptor matches tried in PnP
  int inliers = 0;
  double score = 0.0;  // BoW L1 score of the matched candidate
};

class LoopDetector {
 public:
  LoopDetector(const Vocabulary& vocabulary, const PinholeCamera& camera,
               const LoopDetectorOptions& options = {});

  // Both throw std::invalid_argument when the PlaceView's per-feature arrays differ in size.
  // Loop closing: queries with `keyframe`, then adds it to the database. Returns a verified
  // loop once a candidate group stayed consistent for `consistency` queries.
  std::optional<LoopMatch> process(const PlaceView& keyframe);
  // Relocalisation of a lost frame: no consistency, no recency rule; the frame is not stored.
  std::optional<LoopMatch> relocalize(const PlaceView& frame);
  // Geometric verification of `query` against a stored keyframe.
  std::optional<LoopMatch> verify(const PlaceView& query, const FeatureVector& query_features,
                                  KeyframeId candidate) const;

  void erase(KeyframeId id);
  std::size_t size() const { return stored_.size(); }

 private:
  // What verification needs of a stored keyframe, compact: only the features with a 3D point
  // (the only ones PnP can use), and the vocabulary's direct index over them as flat arrays.
  // A PlaceView and its std::map FeatureVector cost ~100 KB a keyframe; this ~35 KB.
  struct Stored {
    std::vector<OrbDescriptor> descriptors;
    std::vector<Eigen::Vector3f> points_c;  // PnP takes float points anyway
    std::vector<KeyframeId> neighbours;
    std::vector<NodeId> nodes;                 // ascending
    std::vector<std::uint32_t> node_start;     // nodes.size() + 1 offsets into node_features
    std::vector<std::uint16_t> node_features;  // indices into descriptors, ascending per node
  };
  static Stored compact(const PlaceView& view, const FeatureVector& fv);
  std::optional<LoopMatch> verify_candidates(const PlaceView& query, const FeatureVector& fv,
                                             const std::vector<LoopCandidate>& candidates,
                                             const std::vector<std::size_t>& order) const;

  const Vocabulary& vocabulary_;
  PinholeCamera camera_;
  LoopDetectorOptions options_;
  KeyframeDatabase database_;
  ConsistencyChecker checker_;
  std::unordered_map<KeyframeId, Stored> stored_;
};

}  // namespace kestrel::loop
