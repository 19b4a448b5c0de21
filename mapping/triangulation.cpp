#include "mapping/triangulation.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace kestrel::mapping {

namespace {

// Linear triangulation (DLT) of normalized image points x1, x2 seen by cameras T1, T2 (c <- w).
Vec3 triangulate(const SE3& T1, const SE3& T2, const Vec2& x1, const Vec2& x2) {
  const Eigen::Matrix<double, 3, 4> P1 = T1.matrix().topRows<3>();
  const Eigen::Matrix<double, 3, 4> P2 = T2.matrix().topRows<3>();
  Eigen::Matrix4d A;
  A.row(0) = x1.x() * P1.row(2) - P1.row(0);
  A.row(1) = x1.y() * P1.row(2) - P1.row(1);
  A.row(2) = x2.x() * P2.row(2) - P2.row(0);
  A.row(3) = x2.y() * P2.row(2) - P2.row(1);
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (std::abs(X(3)) < 1e-12) return Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  return X.head<3>() / X(3);
}

Mat3 skew(const Vec3& v) {
  Mat3 m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Depths measured at the keyframe's features (appended to z).
void append_feature_depths(const tracking::FrameFeatures& f, std::vector<double>& z) {
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.has_depth(i)) z.push_back(f.depth[i]);
  }
}

// The k-th smallest of z, k = rank(z.size()); 0 for an empty z. Reorders z.
template <typename Rank>
double nth_value(std::vector<double>& z, Rank rank) {
  if (z.empty()) return 0.0;
  const std::size_t k = rank(z.size());
  std::nth_element(z.begin(), z.begin() + static_cast<long>(k), z.end());
  return z[k];
}

double median_depth(const Map& map, const Keyframe& kf) {
  std::vector<double> z;
  const SE3 T_c_w = kf.T_c_w();
  for (PointId p : kf.point_of_feature) {
    if (const MapPoint* mp = map.point(p)) z.push_back((T_c_w * mp->p_w).z());
  }
  append_feature_depths(kf.features, z);
  return nth_value(z, [](std::size_t n) { return n / 2; });
}

// The 99th percentile of a range sensor's readings at the view's features; 0 without any.
double reading_ceiling(const tracking::FrameFeatures& f) {
  if (f.on_depth_step.empty()) return 0.0;
  std::vector<double> z;
  append_feature_depths(f, z);
  return nth_value(
      z, [](std::size_t n) { return static_cast<std::size_t>(0.99 * static_cast<double>(n - 1)); });
}

// has_point: the view's features that observe a point, as the search has left them so far.
bool usable(const TriangulationView& v, const std::vector<std::uint8_t>& has_point, std::size_t i,
            const TriangulationOptions& o) {
  return !has_point[i] && v.features.status[i] == tracking::FeatureStatus::kStatic &&
         !(o.only_without_depth && v.features.has_depth(i)) &&
         !(o.skip_depth_steps && v.features.is_on_depth_step(i));
}

TriangulationView view_of(const Keyframe& kf) {
  TriangulationView v;
  v.id = kf.id;
  v.T_w_c = kf.T_w_c;
  v.features = kf.features;
  // The search reads keypoints, descriptors, depth, status and the outline flags only.
  v.features.points_c.clear();
  v.features.sensor_depth.clear();
  v.features.grid_start.clear();
  v.features.grid_index.clear();
  v.has_point.resize(kf.point_of_feature.size());
  for (std::size_t i = 0; i < kf.point_of_feature.size(); ++i)
    v.has_point[i] = kf.point_of_feature[i] != kNoPoint;
  return v;
}

// A view's feature that can still take a point: the keyframe exists and the feature is free.
bool free_feature(const Map& map, KeyframeId kf, int feature) {
  const Keyframe* k = map.keyframe(kf);
  return k && feature >= 0 && static_cast<std::size_t>(feature) < k->point_of_feature.size() &&
         k->point_of_feature[static_cast<std::size_t>(feature)] == kNoPoint;
}

}  // namespace

std::optional<TriangulationProblem> gather_triangulation(const Map& map, KeyframeId kid,
                                                         const TriangulationOptions& o) {
  const Keyframe* k1 = map.keyframe(kid);
  if (!k1) return std::nullopt;
  TriangulationProblem pb;
  pb.current = view_of(*k1);
  pb.median_depth = median_depth(map, *k1);
  for (KeyframeId id : map.covisible(kid, o.neighbours)) {
    if (const Keyframe* k = map.keyframe(id)) pb.neighbours.push_back(view_of(*k));
  }
  return pb;
}

std::vector<NewMapPoint> solve_triangulation(const TriangulationProblem& pb,
                                             const PinholeCamera& cam,
                                             const TriangulationOptions& o) {
  std::vector<NewMapPoint> out;
  const TriangulationView& k1 = pb.current;
  const tracking::FrameFeatures& f1 = k1.features;
  if (k1.has_point.size() != f1.size()) return out;
  // Which features observe a point, updated as the search creates them.
  std::vector<std::uint8_t> has1 = k1.has_point;
  std::vector<std::vector<std::uint8_t>> has;
  std::vector<SE3> T_c_w;  // each neighbour's, inverted once
  for (const TriangulationView& v : pb.neighbours) {
    has.push_back(v.has_point);
    T_c_w.push_back(v.T_w_c.inverse());
    if (v.has_point.size() != v.features.size()) return out;
  }
  // A third view may confirm with a feature that has depth of its own.
  TriangulationOptions third_view = o;
  third_view.only_without_depth = false;
  const SE3 T1 = k1.T_w_c.inverse();
  const Vec3 c1 = k1.T_w_c.translation();
  const double cos_min_parallax = std::cos(o.min_parallax_deg * M_PI / 180.0);
  const double z1 = pb.median_depth;
  const double min_z1 = o.min_depth_past_readings * reading_ceiling(f1);
  const Mat3 K = cam.K();
  const Mat3 Kinv = K.inverse();
  for (std::size_t n2 = 0; n2 < pb.neighbours.size(); ++n2) {
    const TriangulationView& k2 = pb.neighbours[n2];
    const tracking::FrameFeatures& f2 = k2.features;
    const SE3& T2 = T_c_w[n2];
    const Vec3 c2 = k2.T_w_c.translation();
    const double baseline = (c2 - c1).norm();
    if (z1 > 0.0 && baseline / z1 < o.min_baseline_ratio) continue;
    const double min_z2 = o.min_depth_past_readings * reading_ceiling(f2);
    // Fundamental matrix from keyframe 1's pixels to keyframe 2's: l2 = F21 x1.
    const SE3 T21 = T2 * T1.inverse();
    const Mat3 F21 = Kinv.transpose() * skew(T21.translation()) * T21.rotation() * Kinv;
    std::vector<int> cand2;
    for (std::size_t j = 0; j < f2.size(); ++j) {
      if (usable(k2, has[n2], j, o)) cand2.push_back(static_cast<int>(j));
    }
    if (cand2.empty()) continue;
    // The epipole in keyframe 2: a match too close to it has no parallax along its line.
    const Vec3 e2 = K * (T2 * c1);
    const bool epipole_in_front = e2.z() > 0.0;
    const Vec2 epipole = epipole_in_front ? Vec2(e2.head<2>() / e2.z()) : Vec2::Zero();
    std::vector<char> taken(f2.size(), 0);
    for (std::size_t i = 0; i < f1.size(); ++i) {
      // has1 changes as points are created for i with earlier neighbours.
      if (!usable(k1, has1, i, o)) continue;
      const Vec2& u1 = f1.keypoints[i].un;
      const Vec3 l = F21 * Vec3(u1.x(), u1.y(), 1.0);
      const double ln = std::hypot(l.x(), l.y());
      if (ln < 1e-12) continue;
      int best = -1, best_d = 256, second_d = 256;
      for (int j : cand2) {
        if (taken[static_cast<std::size_t>(j)]) continue;
        const auto& kp2 = f2.keypoints[static_cast<std::size_t>(j)];
        // Matched features see the point at similar scales.
        if (std::abs(kp2.level - f1.keypoints[i].level) > 1) continue;
        const double dist = (l.x() * kp2.un.x() + l.y() * kp2.un.y() + l.z()) / ln;
        if (dist * dist > o.epipolar_chi2 * f2.level_sigma2(kp2.level)) continue;
        if (epipole_in_front) {
          const double sl = f2.level_scale(kp2.level);
          if ((kp2.un - epipole).squaredNorm() < 100.0 * sl * sl) continue;
        }
        const int d =
            tracking::hamming(f1.descriptors[i], f2.descriptors[static_cast<std::size_t>(j)]);
        if (d < best_d) {
          second_d = best_d;
          best_d = d;
          best = j;
        } else if (d < second_d) {
          second_d = d;
        }
      }
      if (best < 0 || best_d > o.max_hamming || best_d > o.ratio * second_d) continue;
      const auto& kp1 = f1.keypoints[i];
      const auto& kp2 = f2.keypoints[static_cast<std::size_t>(best)];
      const Vec3 r1 = Kinv * Vec3(kp1.un.x(), kp1.un.y(), 1.0);
      const Vec3 r2 = Kinv * Vec3(kp2.un.x(), kp2.un.y(), 1.0);
      // Parallax between the rays, in the world frame.
      const Vec3 w1 = k1.T_w_c.rotation() * r1, w2 = k2.T_w_c.rotation() * r2;
      if (w1.normalized().dot(w2.normalized()) > cos_min_parallax) continue;
      const Vec3 X = triangulate(T1, T2, r1.head<2>(), r2.head<2>());
      if (!X.allFinite()) continue;
      const Vec3 x1c = T1 * X, x2c = T2 * X;
      if (x1c.z() <= 0.0 || x2c.z() <= 0.0 || x1c.norm() > o.max_distance) continue;
      if (x1c.z() < min_z1 || x2c.z() < min_z2) continue;
      const auto reproj_ok = [&](const Vec3& xc, const Vec2& un, double sigma2) {
        const Vec2 p(cam.fx * xc.x() / xc.z() + cam.cx, cam.fy * xc.y() / xc.z() + cam.cy);
        return (p - un).squaredNorm() <= o.reprojection_chi2 * sigma2;
      };
      if (!reproj_ok(x1c, kp1.un, f1.level_sigma2(kp1.level)) ||
          !reproj_ok(x2c, kp2.un, f2.level_sigma2(kp2.level))) {
        continue;
      }
      // Scale consistency: the distance ratio must agree with the pyramid levels' ratio.
      const double ratio_dist = (X - c1).norm() / std::max(1e-9, (X - c2).norm());
      const double ratio_octave = f1.level_scale(kp1.level) / f2.level_scale(kp2.level);
      const double sf = 1.5 * f1.scale_factor;
      if (ratio_dist * sf < ratio_octave || ratio_dist > ratio_octave * sf) continue;
      // A third keyframe must see it where it projects: a mover that happened to fit one
      // epipolar line between two views rarely fits a third.
      std::vector<std::pair<std::size_t, int>> more;  // (neighbour, feature)
      if (o.min_views > 2) {
        for (std::size_t n3 = 0; n3 < pb.neighbours.size(); ++n3) {
          if (n3 == n2 || static_cast<int>(more.size()) + 2 >= o.min_views) continue;
          const TriangulationView& k3 = pb.neighbours[n3];
          const Vec3 x3 = T_c_w[n3] * X;
          if (x3.z() <= 0.0) continue;
          const Vec2 p3(cam.fx * x3.x() / x3.z() + cam.cx, cam.fy * x3.y() / x3.z() + cam.cy);
          const tracking::FrameFeatures& f3 = k3.features;
          int best3 = -1, best3_d = o.max_hamming + 1;
          const double r = 2.0 * std::sqrt(o.reprojection_chi2) * f3.level_scale(kp1.level);
          // A linear scan: mapping/ does not link tracking/'s grid (FrameFeatures::in_radius).
          for (std::size_t j = 0; j < f3.size(); ++j) {
            const auto& kp3 = f3.keypoints[j];
            if ((kp3.un - p3).squaredNorm() > r * r || std::abs(kp3.level - kp1.level) > 1 ||
                !usable(k3, has[n3], j, third_view)) {
              continue;
            }
            const int d = tracking::hamming(f1.descriptors[i], f3.descriptors[j]);
            if (d < best3_d) best3_d = d, best3 = static_cast<int>(j);
          }
          if (best3 >= 0) more.emplace_back(n3, best3);
        }
        if (static_cast<int>(more.size()) + 2 < o.min_views) continue;
      }
      NewMapPoint np{X, {{k1.id, static_cast<int>(i)}, {k2.id, best}}};
      has1[i] = 1;
      has[n2][static_cast<std::size_t>(best)] = 1;
      for (const auto& [n3, j] : more) {
        np.views.emplace_back(pb.neighbours[n3].id, j);
        has[n3][static_cast<std::size_t>(j)] = 1;
      }
      out.push_back(std::move(np));
      taken[static_cast<std::size_t>(best)] = 1;
    }
  }
  return out;
}

int apply_triangulation(Map& map, const std::vector<NewMapPoint>& points) {
  int created = 0;
  for (const NewMapPoint& np : points) {
    if (np.views.size() < 2 || !np.p_w.allFinite()) continue;
    if (!free_feature(map, np.views[0].first, np.views[0].second) ||
        !free_feature(map, np.views[1].first, np.views[1].second)) {
      continue;
    }
    const PointId p = map.add_point(np.p_w, np.views[0].first, np.views[0].second);
    for (std::size_t v = 1; v < np.views.size(); ++v) {
      if (v == 1 || free_feature(map, np.views[v].first, np.views[v].second))
        map.add_observation(p, np.views[v].first, np.views[v].second);
    }
    map.update_point(p);
    ++created;
  }
  return created;
}

int triangulate_new_points(Map& map, KeyframeId kid, const PinholeCamera& cam,
                           const TriangulationOptions& o) {
  const auto pb = gather_triangulation(map, kid, o);
  return pb ? apply_triangulation(map, solve_triangulation(*pb, cam, o)) : 0;
}

}  // namespace kestrel::mapping
