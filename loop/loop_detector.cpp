#include "loop/loop_detector.hpp"

#include <algorithm>
#include <limits>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <set>
#include <stdexcept>
#include <string>

namespace kestrel::loop {

LoopDetector::LoopDetector(const Vocabulary& vocabulary, const PinholeCamera& camera,
                           const LoopDetectorOptions& options)
    : vocabulary_(vocabulary),
      camera_(camera),
      options_(options),
      database_(options.database),
      checker_(options.consistency) {}

void LoopDetector::erase(KeyframeId id) {
  database_.erase(id);
  stored_.erase(id);
}

namespace {

void check_sizes(const PlaceView& v) {
  const std::size_t n = v.descriptors.size();
  if (v.keypoints_un.size() != n || v.points_c.size() != n || v.has_point.size() != n)
    throw std::invalid_argument("LoopDetector: PlaceView " + std::to_string(v.id) +
                                " has per-feature arrays of different sizes");
}

}  // namespace

LoopDetector::Stored LoopDetector::compact(const PlaceView& view, const FeatureVector& fv) {
  Stored s;
  s.neighbours = view.neighbours;
  std::vector<int> index_of(view.descriptors.size(), -1);
  for (std::size_t i = 0; i < view.descriptors.size(); ++i) {
    if (!view.has_point[i]) continue;
    index_of[i] = static_cast<int>(s.descriptors.size());
    s.descriptors.push_back(view.descriptors[i]);
    s.points_c.push_back(view.points_c[i].cast<float>());
  }
  if (s.descriptors.size() > std::numeric_limits<std::uint16_t>::max()) {
    throw std::invalid_argument("LoopDetector: PlaceView " + std::to_string(view.id) + " has " +
                                std::to_string(s.descriptors.size()) +
                                " features with points; at most 65535 are stored");
  }
  s.node_start.push_back(0);
  for (const auto& [node, features] : fv) {  // std::map: ascending nodes
    const std::size_t before = s.node_features.size();
    for (int f : features) {
      const int c = index_of[static_cast<std::size_t>(f)];
      if (c >= 0) s.node_features.push_back(static_cast<std::uint16_t>(c));
    }
    if (s.node_features.size() == before) continue;
    s.nodes.push_back(node);
    s.node_start.push_back(static_cast<std::uint32_t>(s.node_features.size()));
  }
  s.descriptors.shrink_to_fit();
  s.points_c.shrink_to_fit();
  s.node_features.shrink_to_fit();
  return s;
}

std::optional<LoopMatch> LoopDetector::process(const PlaceView& keyframe) {
  check_sizes(keyframe);
  FeatureVector fv;
  BowVector bow = vocabulary_.transform(keyframe.descriptors, &fv, options_.direct_depth);
  std::set<KeyframeId> exclude(keyframe.neighbours.begin(), keyframe.neighbours.end());
  exclude.insert(keyframe.id);
  for (const auto& [id, s] : stored_)
    if (id > keyframe.id - options_.recent_exclusion) exclude.insert(id);
  const auto candidates = database_.query(bow, keyframe.neighbours, exclude);

  // A candidate's group is the candidate and its covisible keyframes.
  std::vector<std::set<KeyframeId>> groups;
  for (const auto& c : candidates) {
    std::set<KeyframeId> g{c.id};
    if (const auto it = stored_.find(c.id); it != stored_.end())
      g.insert(it->second.neighbours.begin(), it->second.neighbours.end());
    groups.push_back(std::move(g));
  }
  const std::vector<std::size_t> accepted = checker_.update(groups);
  std::optional<LoopMatch> result;
  if (!accepted.empty()) {
    result = verify_candidates(keyframe, fv, candidates, accepted);
    if (result) checker_.reset();  // a closed loop starts the chains over
  }
  database_.add(keyframe.id, std::move(bow));
  stored_[keyframe.id] = compact(keyframe, fv);
  return result;
}

std::optional<LoopMatch> LoopDetector::relocalize(const PlaceView& frame) {
  check_sizes(frame);
  FeatureVector fv;
  const BowVector bow = vocabulary_.transform(frame.descriptors, &fv, options_.direct_depth);
  // A lost frame has no neighbours to normalise by: raw scores only, best first.
  KeyframeDatabaseOptions o = options_.database;
  o.min_normalized = 0.0;
  const auto candidates = database_.query(bow, {}, {}, o);
  std::vector<std::size_t> order(candidates.size());
  std::iota(order.begin(), order.end(), 0);
  return verify_candidates(frame, fv, candidates, order);
}

std::optional<LoopMatch> LoopDetector::verify_candidates(
    const PlaceView& query, const FeatureVector& fv, const std::vector<LoopCandidate>& candidates,
    const std::vector<std::size_t>& order) const {
  std::optional<LoopMatch> best;
  for (std::size_t i : order) {
    auto m = verify(query, fv, candidates[i].id);
    if (m && (!best || m->inliers > best->inliers)) {
      m->score = candidates[i].score;
      best = m;
    }
  }
  return best;
}

std::optional<LoopMatch> LoopDetector::verify(const PlaceView& query,
                                              const FeatureVector& query_features,
                                              KeyframeId candidate) const {
  const auto it = stored_.find(candidate);
  if (it == stored_.end()) return std::nullopt;
  const Stored& cand = it->second;

  // Guided matching: only features under the same vocabulary node are compared.
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  std::vector<int> used(cand.descriptors.size(), 0);
  for (const auto& [node, q_features] : query_features) {
    const auto n_it = std::lower_bound(cand.nodes.begin(), cand.nodes.end(), node);
    if (n_it == cand.nodes.end() || *n_it != node) continue;
    const auto k = static_cast<std::size_t>(n_it - cand.nodes.begin());
    for (int qi : q_features) {
      int best = std::numeric_limits<int>::max(), second = best, best_ci = -1;
      for (std::uint32_t j = cand.node_start[k]; j < cand.node_start[k + 1]; ++j) {
        const std::size_t c = cand.node_features[j];
        const int d =
            tracking::hamming(query.descriptors[static_cast<std::size_t>(qi)], cand.descriptors[c]);
        if (d < best) {
          second = best;
          best = d;
          best_ci = static_cast<int>(c);
        } else if (d < second) {
          second = d;
        }
      }
      if (best_ci < 0 || best > options_.max_hamming) continue;
      if (second != std::numeric_limits<int>::max() && best > options_.ratio * second) continue;
      if (used[static_cast<std::size_t>(best_ci)]++) continue;  // one query feature per point
      const Eigen::Vector3f& p = cand.points_c[static_cast<std::size_t>(best_ci)];
      const Vec2& u = query.keypoints_un[static_cast<std::size_t>(qi)];
      object.emplace_back(p.x(), p.y(), p.z());
      image.emplace_back(static_cast<float>(u.x()), static_cast<float>(u.y()));
    }
  }
  LoopMatch m;
  m.query = query.id;
  m.match = candidate;
  m.matches = static_cast<int>(object.size());
  if (m.matches < options_.min_inliers) return std::nullopt;

  const cv::Matx33d K(camera_.fx, 0, camera_.cx, 0, camera_.fy, camera_.cy, 0, 0, 1);
  cv::Vec3d rvec, tvec;
  std::vector<int> inliers;
  const bool ok = cv::solvePnPRansac(
      object, image, K, cv::noArray(), rvec, tvec, false, options_.ransac_iterations,
      static_cast<float>(options_.ransac_reprojection_px), 0.99, inliers, cv::SOLVEPNP_EPNP);
  m.inliers = static_cast<int>(inliers.size());
  if (!ok || m.inliers < options_.min_inliers) return std::nullopt;
  // EPnP on a minimal set is rough: refine on all inliers (Levenberg-Marquardt).
  std::vector<cv::Point3f> in_object;
  std::vector<cv::Point2f> in_image;
  for (int i : inliers) {
    in_object.push_back(object[static_cast<std::size_t>(i)]);
    in_image.push_back(image[static_cast<std::size_t>(i)]);
  }
  cv::solvePnPRefineLM(in_object, in_image, K, cv::noArray(), rvec, tvec);
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  Mat4 T = Mat4::Identity();  // T_query_match: candidate camera frame -> query camera frame
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T(r, c) = R(r, c);
    T(r, 3) = tvec[r];
  }
  const SE3 T_query_match(T);
  if (!T_query_match.translation().allFinite()) return std::nullopt;
  m.T_match_query = T_query_match.inverse();
  return m;
}

}  // namespace kestrel::loop
