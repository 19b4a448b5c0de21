#include "tracking/tracker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace kestrel::tracking {

using mapping::KeyframeId;
using mapping::kNoPoint;
using mapping::PointId;

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

const char* to_string(TrackingState s) {
  switch (s) {
    case TrackingState::kInitializing:
      return "initializing";
    case TrackingState::kOk:
      return "ok";
    case TrackingState::kLost:
      return "lost";
    case TrackingState::kRelocalized:
      return "relocalized";
  }
  return "unknown";
}

Tracker::Tracker(const PinholeCamera& camera, const TrackerOptions& options)
    : camera_(camera), options_(options), extractor_(camera, options.features) {}

void Tracker::reset() {
  map_ = mapping::Map();
  state_ = TrackingState::kInitializing;
  last_T_w_c_ = SE3();
  velocity_.reset();
  coast_velocity_.reset();
  lost_frames_ = 0;
  reference_kf_ = last_kf_ = -1;
  last_matches_.clear();
  frames_since_keyframe_ = 0;
  pending_ba_.reset();
  pending_triangulation_.reset();
  pending_kf_ = pending_previous_kf_ = -1;
  culled_.clear();
}

void Tracker::set_map(mapping::Map map) {
  reset();
  map_ = std::move(map);
  if (map_.num_keyframes() == 0) return;  // nothing to relocalize in: initialize as usual
  reference_kf_ = last_kf_ = map_.last_keyframe_id();
  last_T_w_c_ = map_.keyframe(last_kf_)->T_w_c;
  state_ = TrackingState::kLost;
}

TrackResult Tracker::track(const RgbdFrame& frame, const std::optional<SE3>& predicted_T_w_c,
                           const std::vector<std::uint8_t>* keep) {
  const auto t0 = Clock::now();
  FrameFeatures f = extractor_.extract(frame);
  const double extract_ms = ms_since(t0);
  TrackResult r = track(std::move(f), predicted_T_w_c, keep);
  r.times.extract_ms = extract_ms;
  r.times.total_ms += extract_ms;
  return r;
}

void Tracker::set_rotation_prior(const SO3& R_w_c, double sigma_rad) {
  if (!(sigma_rad > 0.0) || !std::isfinite(sigma_rad) || !R_w_c.matrix().allFinite()) {
    rotation_prior_.reset();
    return;
  }
  PosePrior p;
  p.T_c_w = SE3(R_w_c.inverse(), Vec3::Zero());  // the translation carries no information
  p.information.bottomRightCorner<3, 3>() = Mat3::Identity() / (sigma_rad * sigma_rad);
  rotation_prior_ = p;
}

TrackResult Tracker::track(FrameFeatures f, const MotionPrior& prior,
                           const std::vector<std::uint8_t>* keep) {
  const double sr = prior.rotation_sigma, st = prior.translation_sigma;
  if (prior.T_w_c.is_finite() && sr > 0.0 && st > 0.0 && std::isfinite(sr) && std::isfinite(st)) {
    PosePrior p;
    p.T_c_w = prior.T_w_c.inverse();
    p.information.diagonal() << Vec3::Constant(1.0 / (st * st)), Vec3::Constant(1.0 / (sr * sr));
    prior_ = p;
  }
  return track(std::move(f), std::optional<SE3>(prior.T_w_c), keep);
}

TrackResult Tracker::track(FrameFeatures f, const std::optional<SE3>& predicted,
                           const std::vector<std::uint8_t>* keep) {
  const auto t0 = Clock::now();
  // A MotionPrior and a rotation prior hold for this frame only, also when track() throws (a
  // bad keep mask).
  struct ResetPriors {
    Tracker& t;
    ~ResetPriors() {
      t.prior_.reset();
      t.rotation_prior_.reset();
    }
  } reset_priors{*this};
  if (keep) {
    if (keep->size() != f.size()) {
      throw std::invalid_argument("Tracker::track: keep mask has " + std::to_string(keep->size()) +
                                  " entries for " + std::to_string(f.size()) + " features");
    }
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (!(*keep)[i]) f.status[i] = FeatureStatus::kDynamic;
    }
  }
  if (predicted && !predicted->is_finite()) {
    // A broken prediction (e.g. diverged IMU) is no prediction.
    return track(std::move(f), std::nullopt, nullptr);
  }
  if (state_ == TrackingState::kInitializing) {
    busy_ = false;  // set_busy() holds for one track(), this one
    hold_bridge_ = false;
    prior_gate_override_ = 0.0;
    TrackResult r = initialize(std::move(f), predicted);
    r.times.total_ms = ms_since(t0);
    return r;
  }
  const bool busy = std::exchange(busy_, false);
  const bool hold_bridge = std::exchange(hold_bridge_, false);
  const double override_gate = std::exchange(prior_gate_override_, 0.0);
  const double prior_gate = override_gate > 0.0 ? override_gate : options_.prior_gate_chi2;

  TrackResult res;
  const auto tm = Clock::now();
  Matched m;
  PoseOptimizerResult pose;
  pose.ok = false;
  bool relocalizing = state_ == TrackingState::kLost;
  std::vector<PointId> pts;
  std::vector<PointId> visible;
  double optimize_ms = 0.0;

  // Lost a moment ago: where the last motion would have taken the camera by now.
  std::optional<SE3> coast_prior;
  if (relocalizing && coast_velocity_ && lost_frames_ < options_.coast_frames) {
    SE3 T = last_T_w_c_;
    for (int i = 0; i <= lost_frames_; ++i) T = T * *coast_velocity_;
    coast_prior = predicted ? *predicted : T;
  }

  if (!relocalizing || coast_prior) {
    const SE3 prior_w_c =
        coast_prior
            ? *coast_prior
            : (predicted ? *predicted : (velocity_ ? last_T_w_c_ * *velocity_ : last_T_w_c_));
    SE3 start = prior_w_c.inverse();
    pts = local_points();
    // visible: at the predicted pose until a pose is found (what a lost frame reports).
    m = search_local_map(f, start, pts, options_.search_radius_px, &visible);
    if (m.count < options_.min_matches_prior) {
      m = search_local_map(f, start, pts, 2.0 * options_.search_radius_px, nullptr);
    }
    bool tried_pnp = false;
    auto pnp_fallback = [&]() {
      // The prediction is unusable (fast motion, bad prior): descriptor matching + PnP.
      tried_pnp = true;
      int pnp_inliers = 0;
      if (auto T = pnp_against(f, pts, &pnp_inliers)) {
        start = *T;
        m = search_local_map(f, start, pts, options_.search_radius_px, nullptr);
      }
    };
    if (m.count < options_.min_matches_prior) pnp_fallback();
    auto to = Clock::now();
    pose = optimize(f, m, start);
    optimize_ms += ms_since(to);
    // Enough matches around a wrong prior can still be mostly wrong ones.
    if ((!pose.ok || pose.inliers < options_.min_inliers) && !tried_pnp) {
      pnp_fallback();
      to = Clock::now();
      pose = optimize(f, m, start);
      optimize_ms += ms_since(to);
    }
  }
  // A coasting guess must do as well as a relocalization would; else search the whole map
  // (when there is time for it).
  const bool global_search = !busy || options_.busy_relocalize_every <= 1 ||
                             lost_frames_ % options_.busy_relocalize_every == 0;
  if (relocalizing && !(pose.ok && pose.inliers >= options_.min_inliers_relocalize)) {
    pose.ok = false;
    m = Matched{};
    res.global_search_skipped = !global_search;
  }
  if (relocalizing && !pose.ok && global_search) {
    pts = relocalization_candidates(f);
    int pnp_inliers = 0;
    if (auto T = pnp_against(f, pts, &pnp_inliers)) {
      m = search_local_map(f, *T, pts, options_.refine_radius_px * 3.0, nullptr);
      const auto to = Clock::now();
      pose = optimize(f, m, *T);
      optimize_ms += ms_since(to);
    }
  }
  if (pose.ok) {
    // Second pass: with the pose known to a pixel, a tight search finds many more points.
    Matched m2 = search_local_map(f, pose.T_c_w, pts, options_.refine_radius_px, &visible);
    const auto to = Clock::now();
    PoseOptimizerResult pose2 = optimize(f, m2, pose.T_c_w);
    optimize_ms += ms_since(to);
    if (pose2.ok && pose2.inliers >= pose.inliers) {
      pose = pose2;
      m = std::move(m2);
    }
  }
  if (pose.ok && prior_ && prior_gate > 0.0) {
    auto disagreement = [&](const SE3& T_c_w) {
      const Vec6 e = (T_c_w * prior_->T_c_w.inverse()).log();
      return e.allFinite() ? double(e.transpose() * prior_->information * e)
                           : std::numeric_limits<double>::infinity();
    };
    res.prior_chi2 = disagreement(pose.T_c_w);
    if (res.prior_chi2 > prior_gate) {
      // Vision and the IMU disagree: a mover filling the view drags the pose along with it
      // (one walking along the optical axis even passes the epipolar test). The points that
      // project where the IMU says they should are the static ones; they decide, or nothing.
      res.prior_conflict = true;
      std::vector<PointId> visible_p;
      const Matched around =
          search_local_map(f, prior_->T_c_w, pts, options_.refine_radius_px, &visible_p);
      // TrackerOptions::prior_in_conflict: first held by the prior. The held pose must still
      // explain about as many points as vision's own; then vision was only weakly pinned and
      // what pulled it off (movers) is outvoted. Far fewer, and vision is sure of a pose the
      // prediction misses: the points then decide alone, as without the option. Not under a
      // one-frame gate (set_prior_gate_chi2, after frames aligned frame to frame), which asks
      // vision itself to agree.
      const bool hold =
          options_.prior_in_conflict && !options_.prior_in_optimization && override_gate <= 0.0;
      bool taken = false;
      for (const bool held : {true, false}) {
        if (held && !hold) continue;
        Matched mp = around;
        const auto to = Clock::now();
        PoseOptimizerResult pp = optimize(f, mp, prior_->T_c_w, held);
        optimize_ms += ms_since(to);
        const double chi2 = pp.ok ? disagreement(pp.T_c_w) : 0.0;
        if (pp.ok && chi2 <= prior_gate &&
            (!held || pp.inliers >= options_.prior_conflict_min_share * pose.inliers)) {
          pose = pp;
          m = std::move(mp);
          visible = std::move(visible_p);
          res.prior_chi2 = chi2;
          taken = true;
          break;
        }
      }
      if (!taken) pose.ok = false;
    }
  }
  res.times.optimize_ms = optimize_ms;
  res.times.match_ms = ms_since(tm) - optimize_ms;

  // Vision that agrees with the IMU's prediction (within its gate) needs fewer points of its own
  // to be trusted.
  const bool imu_agrees = prior_ && prior_gate > 0.0 && pose.ok && res.prior_chi2 <= prior_gate;
  const int needed = relocalizing ? options_.min_inliers_relocalize
                     : imu_agrees && options_.min_inliers_with_prior > 0
                         ? options_.min_inliers_with_prior
                         : options_.min_inliers;
  bool ok = pose.ok && pose.inliers >= needed && pose.T_c_w.is_finite();
  if (ok && relocalizing) {
    // A relocalization far from where the IMU says the camera is found a look-alike place (a
    // repeated facade, the same shelf twice). Long lost, the position is unknown but the gyro's
    // attitude is not: a corridor seen the other way round looks alike only with the camera
    // turned.
    bool far = false;
    if (predicted && options_.relocalize_max_prediction_m > 0.0) {
      const SE3 d = pose.T_c_w * *predicted;
      far = d.translation().norm() > options_.relocalize_max_prediction_m ||
            d.so3().angle() > options_.relocalize_max_prediction_rad;
    } else if (!predicted && attitude_hint_ && options_.relocalize_max_prediction_rad > 0.0) {
      far = (pose.T_c_w.so3() * *attitude_hint_).angle() > options_.relocalize_max_prediction_rad;
    }
    if (far) {
      ok = false;
      res.relocalization_rejected = true;
    }
  }
  res.matches = m.count;
  res.inliers = ok ? pose.inliers : 0;
  res.local_points = static_cast<int>(pts.size());
  res.visible_points = static_cast<int>(visible.size());
  if (!ok && relocalizing && predicted && !hold_bridge && options_.bridge_after_lost_frames > 0 &&
      lost_frames_ + 1 >= options_.bridge_after_lost_frames) {
    res.times.optimize_ms = optimize_ms;
    const auto tk = Clock::now();
    if (start_local_map(std::move(f), *predicted, res)) {
      res.bridged = true;
      res.times.keyframe_ms = ms_since(tk);
      res.times.total_ms = ms_since(t0);
      return res;
    }
  }
  if (!ok && relocalizing && !predicted && options_.restart_after_lost_frames > 0 &&
      lost_frames_ + 1 >= options_.restart_after_lost_frames) {
    const SE3 T_w_c(attitude_hint_ ? *attitude_hint_ : last_T_w_c_.so3(),
                    last_T_w_c_.translation());
    res.times.optimize_ms = optimize_ms;
    const auto tk = Clock::now();
    if (start_local_map(std::move(f), T_w_c, res)) {
      res.bridged = res.restarted = true;
      res.times.keyframe_ms = ms_since(tk);
      res.times.total_ms = ms_since(t0);
      return res;
    }
  }
  if (!ok) {
    if (relocalizing) {
      ++lost_frames_;
    } else {
      coast_velocity_ = velocity_;
      lost_frames_ = 0;
    }
    state_ = TrackingState::kLost;
    velocity_.reset();
    res.state = state_;
    res.T_w_c = last_T_w_c_;
    res.times.total_ms = ms_since(t0);
    return res;
  }

  const SE3 T_w_c = pose.T_c_w.inverse();
  for (PointId p : visible) {
    if (auto* mp = map_.point(p)) ++mp->visible;
  }
  for (PointId p : m.point) {
    if (auto* mp = map_.point(p)) ++mp->found;
  }
  update_reference(m);
  state_ = relocalizing ? TrackingState::kRelocalized : TrackingState::kOk;
  coast_velocity_.reset();
  lost_frames_ = 0;
  velocity_ =
      relocalizing ? std::optional<SE3>() : std::optional<SE3>(last_T_w_c_.inverse() * T_w_c);
  last_T_w_c_ = T_w_c;
  ++frames_since_keyframe_;

  const auto tk = Clock::now();
  if (need_keyframe(f, m, pose.inliers) || relocalizing) {
    complete_pending_keyframe();
    res.keyframe_id = insert_keyframe(std::move(f), m, T_w_c);
    res.new_keyframe = true;
    res.culled_keyframes = std::move(culled_);
    culled_.clear();
    // Local BA may have refined this keyframe's pose: report and continue from the refined one.
    const SE3 refined = map_.keyframe(res.keyframe_id)->T_w_c;
    if (velocity_) velocity_ = *velocity_ * T_w_c.inverse() * refined;
    last_T_w_c_ = refined;
  }
  res.times.keyframe_ms = ms_since(tk);
  res.T_w_c = last_T_w_c_;
  res.state = state_;
  res.times.total_ms = ms_since(t0);
  return res;
}

TrackResult Tracker::initialize(FrameFeatures&& f, const std::optional<SE3>& predicted) {
  TrackResult res;
  const SE3 T_w_c = predicted ? *predicted : initial_T_w_c_;
  res.T_w_c = T_w_c;
  res.state = TrackingState::kInitializing;
  start_local_map(std::move(f), T_w_c, res);
  return res;
}

bool Tracker::start_local_map(FrameFeatures&& f, const SE3& T_w_c, TrackResult& res) {
  int with_depth = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    with_depth += f.has_depth(i) && f.status[i] == FeatureStatus::kStatic ? 1 : 0;
  }
  if (with_depth < options_.min_init_points) return false;
  complete_pending_keyframe();
  res.culled_keyframes = std::move(culled_);
  culled_.clear();
  const KeyframeId kid = map_.add_keyframe(f.t, T_w_c, std::move(f));
  attach_imu(kid);
  map_.create_points_from_depth(kid, std::numeric_limits<int>::max(), options_.features.max_depth);
  reference_kf_ = last_kf_ = kid;
  frames_since_keyframe_ = 0;
  last_matches_.clear();
  for (PointId p : map_.keyframe(kid)->point_of_feature) {
    if (p != kNoPoint) last_matches_.push_back(p);
  }
  state_ = TrackingState::kOk;
  last_T_w_c_ = T_w_c;
  velocity_.reset();
  coast_velocity_.reset();
  lost_frames_ = 0;
  res.T_w_c = T_w_c;
  res.state = state_;
  res.new_keyframe = true;
  res.keyframe_id = kid;
  res.inliers = res.matches = static_cast<int>(last_matches_.size());
  return true;
}

std::vector<PointId> Tracker::relocalization_candidates(const FrameFeatures& f) const {
  std::vector<PointId> pts;
  const auto cap = static_cast<std::size_t>(std::max(0, options_.relocalize_max_points));
  if (map_.num_points() <= cap) {
    pts.reserve(map_.num_points());
    for (const auto& [id, p] : map_.points()) pts.push_back(id);
    std::sort(pts.begin(), pts.end());  // hash order is not reproducible across builds
    return pts;
  }
  // Keyframe voting: a point votes for its keyframes when some feature of the frame carries
  // nearly its descriptor (ORB-SLAM's TH_LOW).
  constexpr int kVoteDistance = 50;
  std::vector<const OrbDescriptor*> query;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.status[i] == FeatureStatus::kStatic) query.push_back(&f.descriptors[i]);
  }
  std::unordered_map<KeyframeId, int> votes;
  for (const auto& [id, p] : map_.points()) {
    bool hit = false;
    for (const OrbDescriptor* q : query) {
      if (hamming(*q, p.descriptor) < kVoteDistance) {
        hit = true;
        break;
      }
    }
    if (!hit) continue;
    for (const auto& [kf, feature] : p.observations) {
      (void)feature;
      ++votes[kf];
    }
  }
  std::vector<std::pair<int, KeyframeId>> ranked;
  for (const auto& [kf, n] : votes) ranked.emplace_back(n, kf);
  std::sort(ranked.rbegin(), ranked.rend());
  std::vector<KeyframeId> kfs;
  for (std::size_t i = 0; i < ranked.size() && static_cast<int>(i) < options_.relocalize_keyframes;
       ++i) {
    kfs.push_back(ranked[i].second);
    for (KeyframeId k : map_.covisible(ranked[i].second, options_.local_keyframes / 2)) {
      kfs.push_back(k);
    }
  }
  std::sort(kfs.begin(), kfs.end());
  kfs.erase(std::unique(kfs.begin(), kfs.end()), kfs.end());
  for (KeyframeId k : kfs) {
    if (const auto* kf = map_.keyframe(k)) {
      for (PointId p : kf->point_of_feature) {
        if (p != kNoPoint) pts.push_back(p);
      }
    }
  }
  std::sort(pts.begin(), pts.end());
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  if (pts.size() > cap) pts.resize(cap);
  return pts;
}

void Tracker::attach_imu(KeyframeId kid) {
  mapping::Keyframe* kf = map_.keyframe(kid);
  if (gyro_link_ && map_.keyframe(gyro_link_->from)) kf->gyro = gyro_link_;
  kf->v_w = body_velocity_;
}

std::vector<PointId> Tracker::local_points() const {
  // Keyframes that see what the last frame saw, most shared first, plus the reference
  // keyframe's neighbourhood.
  std::unordered_map<KeyframeId, int> counts;
  for (PointId p : last_matches_) {
    if (const auto* mp = map_.point(p)) {
      for (const auto& [kf, feature] : mp->observations) {
        (void)feature;
        ++counts[kf];
      }
    }
  }
  std::vector<std::pair<int, KeyframeId>> ranked;
  for (const auto& [kf, c] : counts) ranked.emplace_back(c, kf);
  std::sort(ranked.rbegin(), ranked.rend());
  std::vector<KeyframeId> kfs;
  for (std::size_t i = 0; i < ranked.size() && static_cast<int>(i) < options_.local_keyframes;
       ++i) {
    kfs.push_back(ranked[i].second);
  }
  kfs.push_back(reference_kf_);
  kfs.push_back(last_kf_);
  for (KeyframeId k : map_.covisible(reference_kf_, options_.local_keyframes / 2)) kfs.push_back(k);
  std::sort(kfs.begin(), kfs.end());
  kfs.erase(std::unique(kfs.begin(), kfs.end()), kfs.end());
  std::vector<PointId> pts;
  for (KeyframeId k : kfs) {
    if (const auto* kf = map_.keyframe(k)) {
      for (PointId p : kf->point_of_feature) {
        if (p != kNoPoint) pts.push_back(p);
      }
    }
  }
  std::sort(pts.begin(), pts.end());
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  return pts;
}

Tracker::Matched Tracker::search_local_map(const FrameFeatures& f, const SE3& T_c_w,
                                           const std::vector<PointId>& pts, double radius,
                                           std::vector<PointId>* visible) const {
  std::vector<ProjectedPoint> proj;
  std::vector<PointId> ids;
  proj.reserve(pts.size());
  ids.reserve(pts.size());
  const Vec3 centre = T_c_w.inverse().translation();
  for (PointId pid : pts) {
    const auto* p = map_.point(pid);
    if (!p) continue;
    const Vec3 p_c = T_c_w * p->p_w;
    if (p_c.z() < 0.05) continue;
    const Vec2 uv(camera_.fx * p_c.x() / p_c.z() + camera_.cx,
                  camera_.fy * p_c.y() / p_c.z() + camera_.cy);
    if (uv.x() < 0 || uv.y() < 0 || uv.x() >= f.width || uv.y() >= f.height) continue;
    const Vec3 ray = p->p_w - centre;
    const double dist = ray.norm();
    if (dist < 0.8 * p->min_distance || dist > 1.2 * p->max_distance) continue;
    if (ray.dot(p->normal) < 0.5 * dist) continue;  // seen more than 60 degrees off its normal
    proj.push_back({uv, p->predict_level(dist, f.scale_factor, f.levels), p->descriptor});
    ids.push_back(pid);
  }
  if (visible) *visible = ids;
  const std::vector<int> match = match_by_projection(f, proj, radius, options_.matching);
  Matched m;
  m.point.assign(f.size(), kNoPoint);
  for (std::size_t k = 0; k < match.size(); ++k) {
    if (match[k] < 0) continue;
    m.point[static_cast<std::size_t>(match[k])] = ids[k];
    ++m.count;
  }
  return m;
}

std::optional<SE3> Tracker::pnp_against(const FrameFeatures& f, const std::vector<PointId>& pts,
                                        int* inliers) const {
  std::vector<OrbDescriptor> train;
  std::vector<const mapping::MapPoint*> train_points;
  for (PointId pid : pts) {
    if (const auto* p = map_.point(pid)) {
      train.push_back(p->descriptor);
      train_points.push_back(p);
    }
  }
  std::vector<OrbDescriptor> query;
  std::vector<int> query_feature;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.status[i] != FeatureStatus::kStatic) continue;
    query.push_back(f.descriptors[i]);
    query_feature.push_back(static_cast<int>(i));
  }
  MatchOptions strict = options_.matching;
  strict.max_distance = std::min(strict.max_distance, 64);
  const std::vector<int> match = match_brute_force(query, train, strict);
  std::vector<Vec3> points_w;
  std::vector<Vec2> uv;
  for (std::size_t q = 0; q < match.size(); ++q) {
    if (match[q] < 0) continue;
    points_w.push_back(train_points[static_cast<std::size_t>(match[q])]->p_w);
    uv.push_back(f.keypoints[static_cast<std::size_t>(query_feature[q])].un);
  }
  const auto r = solve_pnp_ransac(camera_, points_w, uv, options_.pnp);
  if (!r) return std::nullopt;
  *inliers = r->inliers;
  return r->T_c_w;
}

PoseOptimizerResult Tracker::optimize(const FrameFeatures& f, Matched& m, const SE3& T_c_w,
                                      bool with_prior) const {
  std::vector<PoseObservation> obs;
  std::vector<std::size_t> feature_of;
  for (std::size_t i = 0; i < f.size(); ++i) {
    const auto* p = map_.point(m.point[i]);
    if (!p) continue;
    obs.push_back({p->p_w, f.keypoints[i].un, 1.0 / f.level_sigma2(f.keypoints[i].level),
                   f.has_depth(i) ? f.depth[i] : 0.0});
    feature_of.push_back(i);
  }
  const PosePrior* prior = prior_ && (with_prior || options_.prior_in_optimization) ? &*prior_
                           : rotation_prior_ ? &*rotation_prior_
                                             : nullptr;
  PoseOptimizerOptions po = options_.pose;
  po.virtual_bf = options_.ba.virtual_bf;
  PoseOptimizerResult r = optimize_pose(camera_, obs, T_c_w, po, prior);
  m.count = 0;
  for (std::size_t k = 0; k < obs.size(); ++k) {
    if (!r.inlier[k]) {
      m.point[feature_of[k]] = kNoPoint;
    } else {
      ++m.count;
    }
  }
  return r;
}

namespace {

// ORB-SLAM's "close" points (within 40 virtual baselines, about 3 m) are the ones whose depth
// seeds reliable map points. Seen from a drone at 8 m nothing is that close, and seeding only
// the nearest hundred starves the map as it climbs; so "close" stretches to the nearer half of
// what the frame sees, and the disparity term of local BA weighs the far points by their depth.
double close_depth_for(const FrameFeatures& f, double configured) {
  std::vector<double> z;
  z.reserve(f.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.has_depth(i) && f.status[i] == FeatureStatus::kStatic) z.push_back(f.depth[i]);
  }
  if (z.empty()) return configured;
  const auto mid = z.begin() + static_cast<std::ptrdiff_t>(z.size() / 2);
  std::nth_element(z.begin(), mid, z.end());
  return std::max(configured, *mid);
}

}  // namespace

bool Tracker::need_keyframe(const FrameFeatures& f, const Matched& m, int inliers) const {
  if (frames_since_keyframe_ < options_.min_frames_between_keyframes) return false;
  if (pending_kf_ >= 0) return false;  // the local-mapping thread has not finished the last
  const int n_kfs = static_cast<int>(map_.num_keyframes());
  // ORB-SLAM counts an RGB-D observation twice, so its "3 observations" is 2 keyframes here.
  const int min_obs = n_kfs <= 2 ? 1 : 2;
  const int ref_matches = map_.tracked_points(reference_kf_, min_obs);
  int tracked_close = 0, untracked_close = 0, untracked = 0;
  const double close_depth = close_depth_for(f, options_.close_depth);
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (!f.has_depth(i) || f.status[i] != FeatureStatus::kStatic) continue;
    untracked += m.point[i] == kNoPoint ? 1 : 0;
    if (f.depth[i] > close_depth) continue;
    (m.point[i] != kNoPoint ? tracked_close : untracked_close) += 1;
  }
  // TrackerOptions::weak_inliers: weak tracking with unmapped scenery in view.
  const bool weak = inliers < options_.weak_inliers && untracked > options_.weak_new_points;
  const bool need_close = (tracked_close < 100 && untracked_close > 70) || weak;
  const double ratio = n_kfs < 2 ? 0.4 : options_.keyframe_ratio;
  const bool c1 = frames_since_keyframe_ >= options_.max_frames_between_keyframes ||
                  frames_since_keyframe_ >= options_.min_frames_between_keyframes ||
                  inliers < 0.25 * ref_matches || need_close;
  const bool c2 = (inliers < ratio * ref_matches || need_close) && inliers > 15;
  return c1 && c2;
}

KeyframeId Tracker::insert_keyframe(FrameFeatures&& f, const Matched& m, const SE3& T_w_c) {
  const double close_depth = close_depth_for(f, options_.close_depth);
  const KeyframeId kid = map_.add_keyframe(f.t, T_w_c, std::move(f));
  attach_imu(kid);
  for (std::size_t i = 0; i < m.point.size(); ++i) {
    if (m.point[i] != kNoPoint && map_.point(m.point[i])) {
      map_.add_observation(m.point[i], kid, static_cast<int>(i));
      map_.update_point(m.point[i]);
    }
  }
  int created = map_.create_points_from_depth(kid, std::numeric_limits<int>::max(), close_depth);
  if (created < options_.min_new_points) {
    created += map_.create_points_from_depth(kid, options_.min_new_points - created,
                                             options_.features.max_depth);
  }
  map_.update_connections(kid);
  const KeyframeId previous = last_kf_;
  reference_kf_ = last_kf_ = kid;
  frames_since_keyframe_ = 0;
  if (options_.triangulate && !options_.inline_mapping) {
    // The local-mapping thread searches; the frames tracked meanwhile use the depth points.
    pending_triangulation_ = mapping::gather_triangulation(map_, kid, options_.triangulation);
    if (pending_triangulation_) {
      pending_kf_ = kid;
      pending_previous_kf_ = previous;
      track_from_keyframe(kid);
      return kid;
    }
  }
  if (options_.triangulate) {
    mapping::triangulate_new_points(map_, kid, camera_, options_.triangulation);
    map_.update_connections(kid);
  }
  complete_keyframe(kid, previous);
  track_from_keyframe(kid);
  return kid;
}

void Tracker::complete_keyframe(KeyframeId kid, KeyframeId previous) {
  auto t0 = Clock::now();
  map_.cull_points(kid, options_.culling);
  completion_times_.point_culling_ms = ms_since(t0);
  t0 = Clock::now();
  for (KeyframeId id : cull_keyframes(kid, previous)) culled_.push_back(id);
  completion_times_.keyframe_culling_ms = ms_since(t0);
  completion_times_.ba_gather_ms = 0.0;
  if (options_.local_ba) {
    if (options_.inline_mapping) {
      mapping::local_bundle_adjustment(map_, kid, camera_, options_.ba);
    } else {
      // A newer keyframe's window supersedes a request not yet taken.
      t0 = Clock::now();
      pending_ba_ = mapping::gather_local_ba(map_, kid, options_.ba);
      completion_times_.ba_gather_ms = ms_since(t0);
    }
  }
}

void Tracker::track_from_keyframe(KeyframeId kid) {
  last_matches_.clear();
  for (PointId p : map_.keyframe(kid)->point_of_feature) {
    if (p != kNoPoint) last_matches_.push_back(p);
  }
}

std::optional<mapping::TriangulationProblem> Tracker::take_triangulation() {
  std::optional<mapping::TriangulationProblem> out = std::move(pending_triangulation_);
  pending_triangulation_.reset();
  return out;
}

void Tracker::complete_pending_keyframe() {
  if (pending_kf_ < 0) return;
  const KeyframeId kid = pending_kf_;
  pending_kf_ = -1;
  pending_triangulation_.reset();
  if (map_.keyframe(kid)) complete_keyframe(kid, pending_previous_kf_);
}

bool Tracker::finish_keyframe(KeyframeId kid, const std::vector<mapping::NewMapPoint>& points,
                              std::vector<KeyframeId>& culled) {
  if (kid < 0 || kid != pending_kf_) return false;
  pending_kf_ = -1;
  if (!map_.keyframe(kid)) return false;
  auto t0 = Clock::now();
  mapping::apply_triangulation(map_, points);
  completion_times_.triangulation_ms = ms_since(t0);
  t0 = Clock::now();
  map_.update_connections(kid);
  completion_times_.connections_ms = ms_since(t0);
  complete_keyframe(kid, pending_previous_kf_);
  // Frames tracked meanwhile may have chosen as their reference a keyframe culling just erased.
  if (!map_.keyframe(reference_kf_)) reference_kf_ = kid;
  culled.insert(culled.end(), culled_.begin(), culled_.end());
  culled_.clear();
  // No frame tracked since the keyframe (lock-step runs): the next one starts from all of its
  // points, as when the search ran inline.
  if (frames_since_keyframe_ == 0 && kid == last_kf_) track_from_keyframe(kid);
  return true;
}

std::vector<KeyframeId> Tracker::cull_keyframes(KeyframeId newest, KeyframeId previous) {
  std::vector<KeyframeId> culled;
  if (options_.keyframe_cull_redundancy <= 0.0 || map_.num_keyframes() < 3) return culled;
  const KeyframeId first = map_.keyframes().begin()->first;
  std::vector<KeyframeId> candidates;
  for (const auto& [id, w] : map_.keyframe(newest)->connections) {
    (void)w;
    if (id != newest && id != previous && id != first) candidates.push_back(id);
  }
  for (KeyframeId id : candidates) {
    if (map_.is_redundant(id, options_.close_depth, options_.keyframe_cull_observers,
                          options_.keyframe_cull_redundancy)) {
      map_.erase_keyframe(id);
      culled.push_back(id);
    }
  }
  return culled;
}

std::optional<mapping::LocalBaProblem> Tracker::take_local_ba() {
  std::optional<mapping::LocalBaProblem> out = std::move(pending_ba_);
  pending_ba_.reset();
  return out;
}

int Tracker::apply_local_ba(const mapping::LocalBaSolution& solution) {
  const mapping::Keyframe* kf = map_.keyframe(solution.current);
  const std::optional<SE3> before = kf ? std::optional<SE3>(kf->T_w_c) : std::nullopt;
  const int removed = mapping::apply_local_ba(map_, solution);
  // As inline: when no frame has been tracked since its keyframe, the track continues from
  // the refined pose.
  if (before && solution.current == last_kf_ && frames_since_keyframe_ == 0) {
    const SE3 refined = map_.keyframe(last_kf_)->T_w_c;
    if (velocity_) velocity_ = *velocity_ * before->inverse() * refined;
    last_T_w_c_ = refined;
  }
  return removed;
}

void Tracker::update_reference(const Matched& m) {
  std::unordered_map<KeyframeId, int> counts;
  last_matches_.clear();
  for (PointId p : m.point) {
    const auto* mp = map_.point(p);
    if (!mp) continue;
    last_matches_.push_back(p);
    for (const auto& [kf, feature] : mp->observations) {
      (void)feature;
      ++counts[kf];
    }
  }
  int best = 0;
  for (const auto& [kf, c] : counts) {
    if (c > best) {
      best = c;
      reference_kf_ = kf;
    }
  }
}

}  // namespace kestrel::tracking
