#include "dynamic/dynamic_filter.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <unordered_map>

#include "core/camera.hpp"
#include "core/reprojection.hpp"
#include "core/se3.hpp"
#include "dynamic/object_depth.hpp"

namespace kestrel::dynamic {
namespace {

constexpr double kPnpInlierPx = 2.0;

cv::Matx33d to_matx(const Mat3& m) {
  cv::Matx33d out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out(r, c) = m(r, c);
  }
  return out;
}

cv::Mat as_mat(const Image& im) {
  return cv::Mat(im.height, im.width, CV_8UC1, const_cast<std::uint8_t*>(im.data->data()),
                 im.step());
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The depth readings (metres) of the 3x3 window at (u, v), row by row, clipped to the image;
// empty pixels are skipped. `whole`: all nine pixels lie in the image.
struct DepthWindow {
  std::array<double, 9> z{};
  std::size_t count = 0;
  bool whole = false;
};
DepthWindow depth_window(const Image& depth, double scale, int u, int v) {
  DepthWindow w;
  w.whole = u >= 1 && v >= 1 && u + 1 < depth.width && v + 1 < depth.height;
  for (int vv = std::max(0, v - 1); vv <= std::min(depth.height - 1, v + 1); ++vv) {
    const std::uint16_t* row = depth.row<std::uint16_t>(vv);
    for (int uu = std::max(0, u - 1); uu <= std::min(depth.width - 1, u + 1); ++uu)
      if (row[uu] != 0) w.z[w.count++] = row[uu] / scale;
  }
  return w;
}

// The median of a whole window's readings where at least six read and all lie on one surface
// (spread within 10% of it); -1 elsewhere. The median of nine cuts the sensor's per-pixel noise
// about threefold.
double smooth_depth(DepthWindow w) {
  if (!w.whole || w.count < 6) return -1.0;
  const auto end = w.z.begin() + static_cast<long>(w.count);
  const auto mid = w.z.begin() + static_cast<long>(w.count / 2);
  std::nth_element(w.z.begin(), mid, end);
  const double med = *mid;
  const auto [lo, hi] = std::minmax_element(w.z.begin(), end);
  return *hi - *lo <= 0.1 * med ? med : -1.0;
}

// Robust spread: median + k * sigma, sigma from the median absolute deviation.
double adaptive_threshold(const std::vector<double>& values, double k, double floor_px) {
  if (values.size() < 5) return floor_px;
  const double med = median_of(values);
  std::vector<double> dev;
  dev.reserve(values.size());
  for (double v : values) dev.push_back(std::fabs(v - med));
  const double sigma = 1.4826 * median_of(dev);
  return std::max(floor_px, med + k * sigma);
}

double epipolar_distance(const cv::Matx33d& F, const cv::Point2f& prev, const cv::Point2f& cur) {
  const cv::Vec3d l = F * cv::Vec3d(prev.x, prev.y, 1.0);
  const double n = std::hypot(l[0], l[1]);
  if (n < 1e-12) return 0.0;
  return std::fabs(l[0] * cur.x + l[1] * cur.y + l[2]) / n;
}

double homography_residual(const cv::Matx33d& H, const cv::Point2f& prev, const cv::Point2f& cur) {
  const cv::Vec3d p = H * cv::Vec3d(prev.x, prev.y, 1.0);
  if (std::fabs(p[2]) < 1e-12) return 1e9;
  return std::hypot(p[0] / p[2] - cur.x, p[1] / p[2] - cur.y);
}

// Gauss-Newton on the reprojection error of `obj` (current camera frame) seen at `img` (previous
// frame): the motion T (current into previous camera) that PnP-RANSAC found is already close, so
// a few plain least-squares steps converge, at a fraction of solvePnPRefineLM's cost.
SE3 gauss_newton_motion(const PinholeCamera& cam, const std::vector<Vec3>& obj,
                        const std::vector<Vec2>& img, SE3 T) {
  constexpr int kIterations = 6;
  for (int it = 0; it < kIterations; ++it) {
    Mat6 H = Mat6::Zero();
    Vec6 b = Vec6::Zero();
    for (std::size_t k = 0; k < obj.size(); ++k) {
      Vec2 r;
      Mat26 J;
      if (!pose_residual(cam, T, obj[k], img[k], &r, &J)) continue;
      H.noalias() += J.transpose() * J;
      b.noalias() += J.transpose() * r;
    }
    const Vec6 delta = H.ldlt().solve(-b);
    if (!delta.allFinite()) break;
    T = SE3::exp(delta) * T;
    if (delta.squaredNorm() < 1e-14) break;
  }
  return T;
}

// Gauss-Newton on the reprojection error of the points within first_gate_px of the current
// motion, then again on those within kPnpInlierPx of the result. Returns how many points the
// final motion explains to kPnpInlierPx (0 when too few to refine).
int refine_motion(const std::vector<cv::Point3f>& obj, const std::vector<cv::Point2f>& img,
                  const cv::Matx33d& K, double first_gate_px, cv::Mat& rvec, cv::Mat& tvec) {
  PinholeCamera cam;
  cam.fx = K(0, 0);
  cam.fy = K(1, 1);
  cam.cx = K(0, 2);
  cam.cy = K(1, 2);
  cv::Matx33d Rcv;
  cv::Rodrigues(rvec, Rcv);
  Mat3 R;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R(r, c) = Rcv(r, c);
  }
  SE3 T(SO3(R), Vec3(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
  const auto explained = [&](double gate, std::vector<Vec3>* o, std::vector<Vec2>* m) {
    int count = 0;
    for (std::size_t k = 0; k < obj.size(); ++k) {
      const Vec3 X(obj[k].x, obj[k].y, obj[k].z);
      const Vec2 uv(img[k].x, img[k].y);
      Vec2 r;
      if (!pose_residual(cam, T, X, uv, &r) || r.norm() > gate) continue;
      ++count;
      if (o) o->push_back(X);
      if (m) m->push_back(uv);
    }
    return count;
  };
  for (int round = 0; round < 2; ++round) {
    std::vector<Vec3> obj_in;
    std::vector<Vec2> img_in;
    explained(round == 0 ? first_gate_px : kPnpInlierPx, &obj_in, &img_in);
    if (obj_in.size() < 10) return 0;
    T = gauss_newton_motion(cam, obj_in, img_in, T);
  }
  if (!T.is_finite()) return 0;
  cv::Rodrigues(cv::Mat(to_matx(T.rotation())), rvec);
  tvec = (cv::Mat_<double>(3, 1) << T.translation().x(), T.translation().y(), T.translation().z());
  return explained(kPnpInlierPx, nullptr, nullptr);
}

// Whether two camera motions (Rodrigues vector and translation) agree within the gates.
bool motion_agrees(const cv::Mat& r_a, const cv::Mat& t_a, const cv::Mat& r_b, const cv::Mat& t_b,
                   double gate_rad, double gate_m) {
  cv::Matx33d Ra, Rb;
  cv::Rodrigues(r_a, Ra);
  cv::Rodrigues(r_b, Rb);
  cv::Vec3d dr;
  cv::Rodrigues(cv::Mat(Ra * Rb.t()), dr);
  return cv::norm(dr) <= gate_rad && cv::norm(t_a - t_b) <= gate_m;
}

// The pyramid's border is padded for the wider of the two windows, so one pyramid serves both.
int pyramid_window(const DynamicFilterOptions& opt) {
  return std::max(opt.lk_window, opt.lk_window_dim);
}

int pyramid_levels(const DynamicFilterOptions& opt) {
  return std::max(opt.lk_base_level, 0) + std::max({opt.lk_levels, opt.lk_backward_levels, 0});
}

// The pyramid from level `base` up, as calcOpticalFlowPyrLK takes it (image and gradients per
// level): LK then runs on the half- or quarter-resolution image as if it were the full one.
std::vector<cv::Mat> from_level(const std::vector<cv::Mat>& pyramid, int base) {
  const std::size_t skip = std::min(pyramid.size() - 2, 2 * static_cast<std::size_t>(base));
  return {pyramid.begin() + static_cast<long>(skip), pyramid.end()};
}

// Forward (cur -> prev) and backward LK, one pair of calls per window size, each point with its
// own window (windows[k] for from[k]); results land at the points' own indices.
// `to` holds the initial flow where flags ask for it; err is filled only when given.
void flow_by_window(const std::vector<cv::Mat>& cur_levels, const std::vector<cv::Mat>& prev_levels,
                    const std::vector<int>& windows, const DynamicFilterOptions& opt, int levels,
                    int backward_levels, const cv::TermCriteria& term, int flags,
                    const std::vector<cv::Point2f>& from, std::vector<cv::Point2f>& to,
                    std::vector<cv::Point2f>& back, std::vector<unsigned char>& st_f,
                    std::vector<unsigned char>& st_b, std::vector<float>* err,
                    const std::vector<cv::Point2f>* predicted = nullptr, float gate = 0.0f,
                    int* vouched_count = nullptr) {
  std::vector<std::size_t> group;
  std::vector<cv::Point2f> g_from, g_to, g_back;
  std::vector<unsigned char> g_st_f, g_st_b;
  std::vector<float> g_err;
  for (const int window : {opt.lk_window, opt.lk_window_dim}) {
    group.clear();
    for (std::size_t k = 0; k < from.size(); ++k) {
      if (windows[k] == window) group.push_back(k);
    }
    if (group.empty()) continue;
    g_from.resize(group.size());
    g_to.resize(group.size());
    for (std::size_t j = 0; j < group.size(); ++j) {
      g_from[j] = from[group[j]];
      g_to[j] = to[group[j]];
    }
    const cv::Size win(window, window);
    const cv::_OutputArray err_out =
        err ? cv::_OutputArray(g_err) : cv::_OutputArray(cv::noArray());
    cv::calcOpticalFlowPyrLK(cur_levels, prev_levels, g_from, g_to, g_st_f, err_out, win, levels,
                             term, flags, opt.lk_min_eigen);
    // The backward flow, for the features whose forward flow the IMU's motion does not vouch
    // for: a wrong forward track seldom ends where the camera's own motion puts the point. Faint
    // patches (the wider window) are always checked: their flow is noisy enough to land there.
    const bool may_vouch = predicted && gate > 0.0f && window == opt.lk_window;
    std::vector<std::size_t> need;
    need.reserve(group.size());
    for (std::size_t j = 0; j < group.size(); ++j) {
      const std::size_t k = group[j];
      const bool vouched =
          may_vouch && g_st_f[j] && (*predicted)[k].x >= 0.0f &&
          std::hypot(g_to[j].x - (*predicted)[k].x, g_to[j].y - (*predicted)[k].y) <= gate;
      if (!vouched && g_st_f[j]) need.push_back(j);  // a failed forward flow is invalid anyway
      if (vouched && vouched_count) ++*vouched_count;
    }
    std::vector<cv::Point2f> b_from, b_back;
    std::vector<unsigned char> b_st;
    b_from.reserve(need.size());
    for (const std::size_t j : need) {
      b_from.push_back(g_to[j]);
      b_back.push_back(g_from[j]);
    }
    if (!need.empty()) {
      cv::TermCriteria back_term = term;
      if (opt.lk_backward_epsilon_px > 0.0) back_term.epsilon = opt.lk_backward_epsilon_px;
      cv::calcOpticalFlowPyrLK(prev_levels, cur_levels, b_from, b_back, b_st, cv::noArray(), win,
                               backward_levels, back_term, cv::OPTFLOW_USE_INITIAL_FLOW);
    }
    g_back = g_from;
    g_st_b.assign(group.size(), 1);
    for (std::size_t q = 0; q < need.size(); ++q) {
      g_back[need[q]] = b_back[q];
      g_st_b[need[q]] = b_st[q];
    }
    for (std::size_t j = 0; j < group.size(); ++j) {
      const std::size_t k = group[j];
      to[k] = g_to[j];
      back[k] = g_back[j];
      st_f[k] = g_st_f[j];
      st_b[k] = g_st_b[j];
      if (err) (*err)[k] = g_err[j];
    }
    if (opt.lk_window_dim == opt.lk_window) break;
  }
}

// Depth pixels within `r` of a feature (a (2r+1)^2 square, clipped to the image): how many read
// the detected object's depth (within `band` of `d_fg`) and how many lie beyond it.
struct DepthAround {
  int on_object = 0;
  int beyond = 0;
};
DepthAround depth_around(const Image& depth, double scale, const Vec2& p, int r, double d_fg,
                         double band) {
  DepthAround c;
  const int u0 = static_cast<int>(std::lround(p.x())), v0 = static_cast<int>(std::lround(p.y()));
  for (int v = std::max(0, v0 - r); v <= std::min(depth.height - 1, v0 + r); ++v) {
    const std::uint16_t* row = depth.row<std::uint16_t>(v);
    for (int u = std::max(0, u0 - r); u <= std::min(depth.width - 1, u0 + r); ++u) {
      if (!row[u]) continue;
      const double z = row[u] / scale;
      c.on_object += std::fabs(z - d_fg) <= band;
      c.beyond += z > d_fg + band;
    }
  }
  return c;
}

// The point of the segment a..b nearest p.
cv::Point2d closest_on_segment(const cv::Point2d& p, const cv::Point2d& a, const cv::Point2d& b) {
  const cv::Point2d ab = b - a;
  const double len2 = ab.dot(ab);
  return a + (len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0) * ab;
}

// DynamicFilterOptions::far_parallax: for each tracked feature without depth, the distance of
// where the flow puts it in the previous frame to where a static point on its ray could have
// been, between the nearest depth it may have (the sensor's range, or the nearest reading
// around it: an edge's hole) and infinity. X_prev = R X_cur + t. `depth`: the current depth
// image on the grey image's pixels, or null.
void far_parallax_residuals(const DynamicFilterInput& in, const DynamicFilterOptions& opt,
                            const Image* depth, const std::vector<bool>& valid,
                            const std::vector<cv::Point2f>& pts_prev, const cv::Matx33d& R,
                            const cv::Vec3d& t, std::vector<double>& far_residual) {
  const Mat3 Kinv = in.K.inverse();
  const double fx = in.K(0, 0), fy = in.K(1, 1), cx = in.K(0, 2), cy = in.K(1, 2);
  const int w = std::max(0, opt.far_parallax_window_px);
  for (std::size_t i = 0; i < in.points.size(); ++i) {
    if (!valid[i] || (in.depth_m.size() == in.points.size() && in.depth_m[i] > 0)) continue;
    double nearest = in.depth_range_m;
    if (depth) {
      const int u0 = static_cast<int>(std::lround(in.points[i].x()));
      const int v0 = static_cast<int>(std::lround(in.points[i].y()));
      for (int v = std::max(0, v0 - w); v <= std::min(depth->height - 1, v0 + w); ++v) {
        const auto* row = depth->row<std::uint16_t>(v);
        for (int u = std::max(0, u0 - w); u <= std::min(depth->width - 1, u0 + w); ++u)
          if (row[u] > 0) nearest = std::min(nearest, row[u] / in.depth_scale);
      }
    }
    const Vec3 ray = Kinv * Vec3(in.points[i].x(), in.points[i].y(), 1.0);
    const cv::Vec3d r(ray.x(), ray.y(), ray.z());
    // Where a static point at depth z (along the current ray) was in the previous image.
    const auto seen_at = [&](double z) -> std::optional<cv::Point2d> {
      const cv::Vec3d q = std::isinf(z) ? R * r : R * (z * r) + t;
      if (q[2] <= 1e-9) return std::nullopt;
      return cv::Point2d(fx * q[0] / q[2] + cx, fy * q[1] / q[2] + cy);
    };
    const auto far_end = seen_at(std::numeric_limits<double>::infinity());
    const auto near_end = seen_at(nearest);
    if (!far_end || !near_end) continue;
    const cv::Point2d p(pts_prev[i].x, pts_prev[i].y);
    cv::Point2d off = p - closest_on_segment(p, *far_end, *near_end);
    // Or nearer than the sensor measures: from far_parallax_near_m to 5% of it (the camera).
    const double near_m = std::min(opt.far_parallax_near_m, nearest);
    const auto too_near = seen_at(near_m), nearest_end = seen_at(0.05 * near_m);
    if (too_near && nearest_end) {
      const cv::Point2d o2 = p - closest_on_segment(p, *too_near, *nearest_end);
      if (std::hypot(o2.x, o2.y) < std::hypot(off.x, off.y)) off = o2;
    }
    far_residual[i] = std::hypot(off.x, off.y);
  }
}

// Points in square buckets of one radius: a point's neighbours within the radius lie in its own
// bucket and the 8 around it.
class PointBuckets {
 public:
  explicit PointBuckets(double cell) : cell_(cell) {}
  void add(double x, double y, std::size_t id) { grid_[key(bin(x), bin(y))].push_back(id); }
  bool empty() const { return grid_.empty(); }
  // visit(id) for the points of the 9 buckets around (x, y), row by row, each bucket in the
  // order its points were added, until visit returns false.
  template <typename Visit>
  void around(double x, double y, Visit visit) const {
    const std::int64_t cx = bin(x), cy = bin(y);
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const auto it = grid_.find(key(cx + dx, cy + dy));
        if (it == grid_.end()) continue;
        for (std::size_t id : it->second)
          if (!visit(id)) return;
      }
  }

 private:
  std::int64_t bin(double v) const { return static_cast<std::int64_t>(std::floor(v / cell_)); }
  static std::int64_t key(std::int64_t cx, std::int64_t cy) {
    return (cx << 32) ^ (cy & 0xffffffff);
  }
  double cell_;
  std::unordered_map<std::int64_t, std::vector<std::size_t>> grid_;
};

// DynamicFilterOptions::depth_trail: turns `dev` (per feature, the previous depth read minus the
// depth the ego-motion predicts there, metres; NaN unknown) into what the trail sums: less this
// frame's common offset over `background` (the ego-motion's error along the view), over depth^2
// (the sensor's noise grows so), averaged with its neighbours' on the same surface. Returns the
// threshold for one frame's departure, depth_k robust sigmas of the background's, and leaves NaN
// beyond depth_trail_max_m and above depth_trail_jump thresholds (an occluder passing, not a
// surface drifting). Too little background: `dev` emptied, nothing to sum.
double depth_departures(const DynamicFilterInput& in, const DynamicFilterOptions& opt,
                        const std::vector<std::size_t>& background, std::vector<double>& dev) {
  const std::size_t n = dev.size();
  std::vector<double> offsets;
  for (std::size_t i : background)
    if (!std::isnan(dev[i])) offsets.push_back(dev[i]);
  const double offset = offsets.size() >= 5 ? median_of(offsets) : 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isnan(dev[i])) continue;
    const double z = in.depth_m[i];
    dev[i] = (dev[i] - offset) / (z * z);
  }
  const double r = opt.depth_trail_pool_px;
  if (r > 0) {
    PointBuckets grid(r);
    for (std::size_t i = 0; i < n; ++i)
      if (!std::isnan(dev[i])) grid.add(in.points[i].x(), in.points[i].y(), i);
    std::vector<double> pooled = dev;
    for (std::size_t i = 0; i < n; ++i) {
      if (std::isnan(dev[i])) continue;
      double sum = 0.0;
      int count = 0;
      const double z = in.depth_m[i];
      grid.around(in.points[i].x(), in.points[i].y(), [&](std::size_t j) {
        if ((in.points[j] - in.points[i]).squaredNorm() <= r * r &&
            std::fabs(in.depth_m[j] - z) <= opt.depth_trail_same_surface * z) {
          sum += dev[j];
          ++count;
        }
        return true;
      });
      pooled[i] = sum / count;
    }
    dev = std::move(pooled);
  }
  std::vector<double> spread;
  for (std::size_t i : background)
    if (!std::isnan(dev[i])) spread.push_back(std::fabs(dev[i]));
  if (spread.size() < 5) {
    dev.clear();  // too little background to tell noise from motion
    return 0.0;
  }
  const double thr = opt.depth_k * 1.4826 * median_of(spread);
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isnan(dev[i]) &&
        (in.depth_m[i] > opt.depth_trail_max_m || std::fabs(dev[i]) > opt.depth_trail_jump * thr))
      dev[i] = std::numeric_limits<double>::quiet_NaN();
  return thr;
}

// DynamicFilterOptions::trail: each feature with a departure carries on the trail of the
// previous frame's feature its flow starts at. Returns, per feature, whether its summed
// departure says it moved.
std::vector<bool> follow_trail(const DynamicFilterInput& in, const DynamicFilterOptions& opt,
                               const std::vector<cv::Point2f>& pts_prev,
                               const std::vector<double>& residual3d,
                               const std::vector<cv::Point2f>& departure, double thr3d,
                               const std::vector<double>& depth_dev, double thr_depth_dev,
                               ResidualTrail& trail) {
  const std::size_t n = in.points.size();
  trail.points = in.points;
  trail.departure.assign(n, Vec2::Zero());
  trail.weight.assign(n, 0.0);
  trail.weight2.assign(n, 0.0);
  trail.depth_departure.assign(n, 0.0);
  trail.depth_weight.assign(n, 0.0);
  trail.depth_weight2.assign(n, 0.0);
  trail.depth = in.depth_m.size() == n ? in.depth_m : std::vector<double>(n, 0.0);
  std::vector<bool> moved(n, false);
  const ResidualTrail* prev = in.prev_trail;
  const std::size_t m = prev ? prev->points.size() : 0;
  const bool linked = prev && prev->departure.size() == m && prev->weight.size() == m &&
                      prev->weight2.size() == m && prev->depth_departure.size() == m &&
                      prev->depth_weight.size() == m && prev->depth_weight2.size() == m &&
                      prev->depth.size() == m;
  PointBuckets grid(std::max(opt.trail_link_px, 0.5));
  PointBuckets depth_grid(std::max(opt.depth_trail_link_px, 0.5));
  if (linked)
    for (std::size_t j = 0; j < m; ++j) {
      if (prev->weight[j] > 0.0) grid.add(prev->points[j].x(), prev->points[j].y(), j);
      if (prev->depth_weight[j] > 0.0) depth_grid.add(prev->points[j].x(), prev->points[j].y(), j);
    }
  const double r2 = opt.trail_link_px * opt.trail_link_px;
  const double rd2 = opt.depth_trail_link_px * opt.depth_trail_link_px;
  // The previous frame's feature in `g` nearest `p` within sqrt(max_d2) that `accept`s.
  const auto nearest = [&](const PointBuckets& g, const cv::Point2f& p, double max_d2,
                           const auto& accept) {
    double best = max_d2;
    std::optional<std::size_t> from;
    g.around(p.x, p.y, [&](std::size_t j) {
      const double ex = prev->points[j].x() - p.x, ey = prev->points[j].y() - p.y;
      if (ex * ex + ey * ey <= best && accept(j)) {
        best = ex * ex + ey * ey;
        from = j;
      }
      return true;
    });
    return from;
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (residual3d[i] < 0) continue;
    const Vec2 d(departure[i].x, departure[i].y);
    double w = 1.0, w2 = 1.0;
    Vec2 sum = d;
    const bool has_dd = depth_dev.size() == n && !std::isnan(depth_dev[i]);
    double dsum = has_dd ? depth_dev[i] : 0.0, dw = has_dd ? 1.0 : 0.0, dw2 = dw;
    if (!grid.empty()) {
      const auto from = nearest(grid, pts_prev[i], r2, [](std::size_t) { return true; });
      if (from) {
        const double a = opt.trail_decay;
        sum += a * prev->departure[*from];
        w += a * prev->weight[*from];
        w2 += a * a * prev->weight2[*from];
      }
    }
    if (has_dd && !depth_grid.empty()) {
      // A surface moves as one: the previous frame's feature on the same surface nearest where
      // the flow starts carries its trail on, though the same corner is seldom found again.
      const double z = in.depth_m[i];
      const auto from = nearest(depth_grid, pts_prev[i], rd2, [&](std::size_t j) {
        return std::fabs(prev->depth[j] - z) <= opt.depth_trail_same_surface * z;
      });
      if (from) {
        const double a = opt.trail_decay;
        dsum += a * prev->depth_departure[*from];
        dw += a * prev->depth_weight[*from];
        dw2 += a * a * prev->depth_weight2[*from];
      }
    }
    trail.departure[i] = sum;
    trail.weight[i] = w;
    trail.weight2[i] = w2;
    trail.depth_departure[i] = dsum;
    trail.depth_weight[i] = dw;
    trail.depth_weight2[i] = dw2;
    moved[i] = (w >= opt.trail_min_weight && sum.norm() > opt.trail_k * thr3d * std::sqrt(w2)) ||
               (dw >= opt.trail_min_weight &&
                std::fabs(dsum) > opt.trail_k * thr_depth_dev * std::sqrt(dw2));
  }
  return moved;
}

// Step 7 of classify_features (DynamicFilterOptions::coherent_neighbours): `departure[i]` is
// where the flow put feature i in the previous frame minus where the ego-motion puts it.
void demote_incoherent_flow(const std::vector<cv::Point2f>& pts_cur,
                            const std::vector<cv::Point2f>& departure,
                            const DynamicFilterOptions& opt, DynamicFilterResult& out) {
  const std::size_t n = pts_cur.size();
  // Any feature found moving with its 3D residual known may vouch for a neighbour (a walker's
  // arm outside its box moves as its box's features do); only those flagged outside boxes by
  // that residual alone are in question.
  std::vector<std::size_t> flagged, witnesses;
  for (std::size_t i = 0; i < n; ++i) {
    if (out.labels[i] != FeatureLabel::kDynamic || out.residual3d_px[i] < 0) continue;
    witnesses.push_back(i);
    if (out.reasons[i] == LabelReason::kFlowResidual) flagged.push_back(i);
  }
  if (flagged.empty()) return;
  PointBuckets grid(std::max(opt.coherence_radius_px, 1.0));
  for (std::size_t i : witnesses) grid.add(pts_cur[i].x, pts_cur[i].y, i);
  const double r2 = opt.coherence_radius_px * opt.coherence_radius_px;
  std::vector<std::size_t> demote;
  for (std::size_t i : flagged) {
    const cv::Point2f di = departure[i];
    const double tol = std::max(2.0, 0.3 * std::hypot(di.x, di.y));
    int agreeing = 0;
    if (opt.coherent_neighbours > 0)
      grid.around(pts_cur[i].x, pts_cur[i].y, [&](std::size_t j) {
        if (j == i) return true;
        const cv::Point2f d = pts_cur[j] - pts_cur[i];
        if (double(d.x) * d.x + double(d.y) * d.y > r2) return true;
        const cv::Point2f dd = departure[j] - di;
        return !(std::hypot(dd.x, dd.y) <= tol && ++agreeing >= opt.coherent_neighbours);
      });
    if (agreeing < opt.coherent_neighbours) demote.push_back(i);
  }
  // Judged against the witnesses as they were, so the order of the features does not matter.
  for (std::size_t i : demote) {
    out.labels[i] = FeatureLabel::kUnknown;
    out.reasons[i] = LabelReason::kIncoherentFlow;
  }
}

}  // namespace

struct FlowPyramid::Levels {
  std::vector<cv::Mat> pyramid;  // image and gradient levels, as cv::buildOpticalFlowPyramid
  int requested_levels = 0;      // levels above the image asked for (fewer on a small image)
  int window = 0;
  std::shared_ptr<const std::vector<std::uint8_t>> source;  // the pixels it was built from
  int width = 0, height = 0;

  bool built_from(const Image& im, int win, int lv) const {
    return source == im.data && width == im.width && height == im.height && window == win &&
           requested_levels == lv;
  }
};

FlowPyramid build_flow_pyramid(const Image& gray, const DynamicFilterOptions& opt) {
  if (gray.empty() || gray.channels != 1 || gray.type != PixelType::kU8) {
    throw std::invalid_argument("build_flow_pyramid: the image must be 8-bit, one channel");
  }
  auto lv = std::make_shared<FlowPyramid::Levels>();
  const cv::Size win(pyramid_window(opt), pyramid_window(opt));
  lv->requested_levels = pyramid_levels(opt);
  cv::buildOpticalFlowPyramid(as_mat(gray), lv->pyramid, win, lv->requested_levels, true,
                              cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT, false);
  lv->window = pyramid_window(opt);
  lv->source = gray.data;
  lv->width = gray.width;
  lv->height = gray.height;
  return FlowPyramid{std::move(lv)};
}

namespace {

// The interior pixels of the window x window patch at (x, y) of a width x height image.
struct PatchSpan {
  int u_lo, u_hi, v_lo, v_hi;
};
PatchSpan interior_patch(int width, int height, double x, double y, int window) {
  const int half = std::max(window, 1) / 2;
  const int u0 = static_cast<int>(std::lround(x)), v0 = static_cast<int>(std::lround(y));
  return {std::max(1, u0 - half), std::min(width - 2, u0 + half), std::max(1, v0 - half),
          std::min(height - 2, v0 + half)};
}

// weakest_gradient from the sums of the Scharr structure tensor over `count` pixels.
double weakest_from_tensor(std::int64_t s11, std::int64_t s12, std::int64_t s22, int count) {
  if (count == 0) return 0.0;
  const double norm = 1.0 / (32.0 * 32.0 * count);
  const double a11 = static_cast<double>(s11) * norm, a12 = static_cast<double>(s12) * norm,
               a22 = static_cast<double>(s22) * norm;
  const double lmin = 0.5 * (a11 + a22 - std::sqrt((a11 - a22) * (a11 - a22) + 4.0 * a12 * a12));
  return std::sqrt(std::max(lmin, 0.0));
}

// The same from the level-0 derivatives buildOpticalFlowPyramid already computed for the flow
// (CV_16SC2, dx and dy by the same unnormalised Scharr kernel, exact in 16 bits): identical
// values, without computing the kernel a second time.
double weakest_gradient_of_derivatives(const cv::Mat& deriv, double x, double y, int window) {
  const PatchSpan p = interior_patch(deriv.cols, deriv.rows, x, y, window);
  std::int64_t s11 = 0, s12 = 0, s22 = 0;
  int count = 0;
  for (int v = p.v_lo; v <= p.v_hi; ++v) {
    const cv::Vec2s* row = deriv.ptr<cv::Vec2s>(v);
    for (int u = p.u_lo; u <= p.u_hi; ++u) {
      const int gx = row[u][0], gy = row[u][1];
      s11 += gx * gx;
      s12 += gx * gy;
      s22 += gy * gy;
      ++count;
    }
  }
  return weakest_from_tensor(s11, s12, s22, count);
}

}  // namespace

double weakest_gradient(const Image& gray, double x, double y, int window) {
  if (gray.empty() || gray.channels != 1 || gray.type != PixelType::kU8) {
    throw std::invalid_argument("weakest_gradient: an 8-bit grey image is required");
  }
  // Scharr's kernel over interior pixels, divided by its weight (32): grey levels per pixel.
  const PatchSpan p = interior_patch(gray.width, gray.height, x, y, window);
  std::int64_t s11 = 0, s12 = 0, s22 = 0;
  int count = 0;
  for (int v = p.v_lo; v <= p.v_hi; ++v) {
    const std::uint8_t* up = gray.row<std::uint8_t>(v - 1);
    const std::uint8_t* mid = gray.row<std::uint8_t>(v);
    const std::uint8_t* down = gray.row<std::uint8_t>(v + 1);
    for (int u = p.u_lo; u <= p.u_hi; ++u) {
      const int gx = 3 * (up[u + 1] - up[u - 1]) + 10 * (mid[u + 1] - mid[u - 1]) +
                     3 * (down[u + 1] - down[u - 1]);
      const int gy =
          3 * (down[u - 1] - up[u - 1]) + 10 * (down[u] - up[u]) + 3 * (down[u + 1] - up[u + 1]);
      s11 += gx * gx;
      s12 += gx * gy;
      s22 += gy * gy;
      ++count;
    }
  }
  return weakest_from_tensor(s11, s12, s22, count);
}

namespace {

// lk_window_dim where `texture(x, y)` (weakest_gradient over the lk_window patch) is below
// dim_texture, lk_window elsewhere.
template <class Texture>
std::vector<int> windows_by_texture(const std::vector<Vec2>& points,
                                    const DynamicFilterOptions& opt, Texture texture) {
  std::vector<int> out(points.size(), opt.lk_window);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (texture(points[i].x(), points[i].y()) < opt.dim_texture) out[i] = opt.lk_window_dim;
  }
  return out;
}

}  // namespace

std::vector<int> flow_windows(const Image& cur_gray, const std::vector<Vec2>& points,
                              const DynamicFilterOptions& opt) {
  if (opt.lk_window_dim <= 0 || cur_gray.empty() || cur_gray.channels != 1 ||
      cur_gray.type != PixelType::kU8) {
    return std::vector<int>(points.size(), opt.lk_window);
  }
  return windows_by_texture(points, opt, [&](double x, double y) {
    return weakest_gradient(cur_gray, x, y, opt.lk_window);
  });
}

std::vector<int> flow_windows(const FlowPyramid& cur, const std::vector<Vec2>& points,
                              const DynamicFilterOptions& opt) {
  if (opt.lk_window_dim <= 0 || cur.empty()) return std::vector<int>(points.size(), opt.lk_window);
  const cv::Mat& deriv = cur.levels->pyramid.at(1);  // level 0's, after the image
  return windows_by_texture(points, opt, [&](double x, double y) {
    return weakest_gradient_of_derivatives(deriv, x, y, opt.lk_window);
  });
}

const char* to_string(LabelReason r) {
  switch (r) {
    case LabelReason::kStaticGeometry:
      return "static-geometry";
    case LabelReason::kStaticInBox:
      return "static-in-box";
    case LabelReason::kEpipolarInBox:
      return "epipolar-in-box";
    case LabelReason::kMovingBox:
      return "moving-box";
    case LabelReason::kEpipolarOutside:
      return "epipolar-outside";
    case LabelReason::kFlowResidual:
      return "flow-residual";
    case LabelReason::kNoFlowInBox:
      return "no-flow-in-box";
    case LabelReason::kNoFlow:
      return "no-flow";
    case LabelReason::kNoGeometry:
      return "no-geometry";
    case LabelReason::kForegroundInBox:
      return "foreground-in-box";
    case LabelReason::kDepthChange:
      return "depth-change";
    case LabelReason::kLongBaseline:
      return "long-baseline";
    case LabelReason::kOutlineBackground:
      return "outline-background";
    case LabelReason::kOutlineNoDepth:
      return "outline-no-depth";
    case LabelReason::kFarBoxNoDepth:
      return "far-box-no-depth";
    case LabelReason::kIncoherentFlow:
      return "incoherent-flow";
    case LabelReason::kAmbiguousFlow:
      return "ambiguous-flow";
    case LabelReason::kFarParallax:
      return "far-parallax";
    case LabelReason::kRimOnObject:
      return "rim-on-object";
  }
  return "?";
}

const char* to_string(FilterMode m) {
  switch (m) {
    case FilterMode::kHybrid:
      return "hybrid";
    case FilterMode::kDetectionOnly:
      return "detection";
    case FilterMode::kGeometryOnly:
      return "geometry";
    case FilterMode::kOff:
      return "off";
  }
  return "?";
}

std::optional<FilterMode> filter_mode_from_string(const std::string& name) {
  if (name == "hybrid") return FilterMode::kHybrid;
  if (name == "detection") return FilterMode::kDetectionOnly;
  if (name == "geometry") return FilterMode::kGeometryOnly;
  if (name == "off") return FilterMode::kOff;
  return std::nullopt;
}

std::size_t DynamicFilterResult::count(FeatureLabel l) const {
  return static_cast<std::size_t>(std::count(labels.begin(), labels.end(), l));
}

DynamicFilterResult classify_features(const DynamicFilterInput& in,
                                      const DynamicFilterOptions& opt) {
  const std::size_t n = in.points.size();
  DynamicFilterResult out;
  out.labels.assign(n, FeatureLabel::kStatic);
  out.reasons.assign(n, LabelReason::kStaticGeometry);
  out.epipolar_px.assign(n, -1.0f);
  out.residual_px.assign(n, -1.0f);
  out.residual3d_px.assign(n, -1.0f);
  out.depth_change.assign(n, -1.0f);
  out.far_residual_px.assign(n, -1.0f);
  out.box_of.assign(n, -1);
  out.prev_points.assign(n, Vec2(-1.0, -1.0));
  out.box_moving.assign(in.boxes.size(), false);
  out.box_features.assign(in.boxes.size(), 0);
  out.box_violating.assign(in.boxes.size(), 0);
  if (n == 0 || opt.mode == FilterMode::kOff) return out;

  const bool use_boxes = opt.mode != FilterMode::kGeometryOnly;
  const bool use_geometry = opt.mode != FilterMode::kDetectionOnly;
  // The current frame's pyramid comes first where the flow needs it: its level-0 derivatives
  // give each feature's texture (flow_windows) without a second pass over the patches.
  const bool grey_pair = in.prev_gray && in.cur_gray;
  const FlowPyramid cur_pyr =
      use_geometry && grey_pair ? build_flow_pyramid(*in.cur_gray, opt) : FlowPyramid{};
  const std::vector<int> windows = !cur_pyr.empty() ? flow_windows(cur_pyr, in.points, opt)
                                   : in.cur_gray    ? flow_windows(*in.cur_gray, in.points, opt)
                                                    : std::vector<int>(n, opt.lk_window);

  // Which boxes hold each feature (a feature may sit in two overlapping boxes).
  std::vector<std::vector<int>> boxes_of(n);
  if (use_boxes) {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t b = 0; b < in.boxes.size(); ++b) {
        if (in.boxes[b].contains(static_cast<float>(in.points[i].x()),
                                 static_cast<float>(in.points[i].y()))) {
          boxes_of[i].push_back(static_cast<int>(b));
        }
      }
      if (!boxes_of[i].empty()) out.box_of[i] = boxes_of[i].front();
    }
  }

  // The detected object's own depth: the median depth of the box's core (its central part,
  // where a person's torso or a car's body is), and which features lie at that depth.
  std::vector<bool> foreground(n, false);
  std::vector<bool> on_rim(n, false);            // foreground by its pixels' depth, not its own
  std::vector<bool> far_box_no_depth(n, false);  // DynamicFilterOptions::far_box_no_depth_dynamic
  // 1: behind the object with its window on the object's outline; 2: the same without depth.
  std::vector<std::uint8_t> outline(n, 0);
  // Only a depth image on the grey image's own pixels (registered) says what lies under a box.
  const bool depth_image = in.cur_depth && !in.cur_depth->empty() &&
                           in.cur_depth->type == PixelType::kU16 && in.cur_depth->channels == 1 &&
                           (!in.cur_gray || (in.cur_depth->width == in.cur_gray->width &&
                                             in.cur_depth->height == in.cur_gray->height));
  if (use_boxes && in.depth_m.size() == n) {
    for (std::size_t b = 0; b < in.boxes.size(); ++b) {
      const BoxRegion& box = in.boxes[b];
      const BoxRegion core = box_core(box);
      std::vector<double> core_depths;
      for (std::size_t i = 0; i < n; ++i) {
        if (in.depth_m[i] > 0 && core.contains(static_cast<float>(in.points[i].x()),
                                               static_cast<float>(in.points[i].y()))) {
          core_depths.push_back(in.depth_m[i]);
        }
      }
      // With the depth image, the object's depth comes from the core's pixels, not from its
      // features: ORB corners crowd onto the textured scenery behind a walker, so their median
      // can be the background's while the walker covers most of the core.
      if (depth_image && opt.dense_core_depth && core_depths.size() >= 3) {
        std::vector<double> surface = largest_surface(*in.cur_depth, in.depth_scale, core, opt);
        if (surface.size() >= 8) core_depths = std::move(surface);
      }
      if (core_depths.size() < 3) {
        if (opt.far_box_no_depth_dynamic) {
          for (std::size_t i = 0; i < n; ++i) {
            if (in.depth_m[i] <= 0 && std::find(boxes_of[i].begin(), boxes_of[i].end(),
                                                static_cast<int>(b)) != boxes_of[i].end()) {
              far_box_no_depth[i] = true;
            }
          }
        }
        continue;
      }
      const double d_fg = median_of(core_depths);
      const double band = foreground_band(d_fg, opt);
      for (std::size_t i = 0; i < n; ++i) {
        if (in.depth_m[i] > 0 && std::fabs(in.depth_m[i] - d_fg) <= band &&
            std::find(boxes_of[i].begin(), boxes_of[i].end(), static_cast<int>(b)) !=
                boxes_of[i].end()) {
          foreground[i] = true;
        }
      }
      if (depth_image && opt.silhouette_object_pixels > 0) {
        for (std::size_t i = 0; i < n; ++i) {
          if (in.depth_m[i] > 0 || foreground[i] ||
              std::find(boxes_of[i].begin(), boxes_of[i].end(), static_cast<int>(b)) ==
                  boxes_of[i].end()) {
            continue;
          }
          const DepthAround c =
              depth_around(*in.cur_depth, in.depth_scale, in.points[i], 1, d_fg, band);
          if (c.on_object >= opt.silhouette_object_pixels) foreground[i] = on_rim[i] = true;
        }
      }
      if (!depth_image || !opt.outline_by_depth) continue;
      for (std::size_t i = 0; i < n; ++i) {
        const int r = std::max(1, windows[i] / 2);
        if (foreground[i] || outline[i] ||
            std::find(boxes_of[i].begin(), boxes_of[i].end(), static_cast<int>(b)) ==
                boxes_of[i].end()) {
          continue;
        }
        const bool behind = in.depth_m[i] > d_fg + band;
        const bool no_depth = in.depth_m[i] <= 0;
        if (!behind && !no_depth) continue;
        const DepthAround c =
            depth_around(*in.cur_depth, in.depth_scale, in.points[i], r, d_fg, band);
        if (c.on_object && c.beyond) outline[i] = behind ? 1 : 2;
      }
    }
  }

  if (!use_geometry) {
    for (std::size_t i = 0; i < n; ++i) {
      if (!boxes_of[i].empty()) {
        out.labels[i] = FeatureLabel::kDynamic;
        out.reasons[i] = LabelReason::kNoGeometry;
      }
    }
    for (std::size_t b = 0; b < in.boxes.size(); ++b) out.box_moving[b] = true;
    return out;
  }

  // 1. Flow from the current frame back to the previous one, forward-backward checked, on
  // pyramids built once per image (the previous one usually comes from the call before).
  if (!grey_pair) {
    throw std::invalid_argument("classify_features: prev_gray and cur_gray are required");
  }
  const FlowPyramid prev_pyr = in.prev_pyramid && !in.prev_pyramid->empty() &&
                                       in.prev_pyramid->levels->built_from(
                                           *in.prev_gray, pyramid_window(opt), pyramid_levels(opt))
                                   ? *in.prev_pyramid
                                   : build_flow_pyramid(*in.prev_gray, opt);
  if (in.cur_pyramid_out) *in.cur_pyramid_out = cur_pyr;
  const int prev_cols = in.prev_gray->width, prev_rows = in.prev_gray->height;
  std::vector<cv::Point2f> pts_cur(n), pts_prev(n), pts_back;
  for (std::size_t i = 0; i < n; ++i) {
    pts_cur[i] =
        cv::Point2f(static_cast<float>(in.points[i].x()), static_cast<float>(in.points[i].y()));
  }
  // Initial flow: where the IMU rotation puts each point in the previous frame (the rotation
  // homography's inverse, K R^T K^-1); without it, the point itself.
  const int levels = opt.lk_levels;
  int flags = 0;
  if (in.R_cur_prev && opt.lk_rotation_prior) {
    const cv::Matx33d H_prev_cur = to_matx(in.K * in.R_cur_prev->transpose() * in.K.inverse());
    for (std::size_t i = 0; i < n; ++i) {
      const cv::Vec3d p = H_prev_cur * cv::Vec3d(pts_cur[i].x, pts_cur[i].y, 1.0);
      pts_prev[i] = std::fabs(p[2]) > 1e-12 ? cv::Point2f(static_cast<float>(p[0] / p[2]),
                                                          static_cast<float>(p[1] / p[2]))
                                            : pts_cur[i];
    }
    flags = cv::OPTFLOW_USE_INITIAL_FLOW;
  }
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, opt.lk_iterations,
                              opt.lk_epsilon_px);
  // Flow on the pyramid from lk_base_level up, in that level's pixels (OpenCV's convention:
  // level-l coordinates are full-resolution ones over 2^l), scaled back afterwards.
  const int base = std::max(opt.lk_base_level, 0);
  const float scale = static_cast<float>(1 << base);
  const std::vector<cv::Mat> cur_levels = from_level(cur_pyr.levels->pyramid, base);
  const std::vector<cv::Mat> prev_levels = from_level(prev_pyr.levels->pyramid, base);
  std::vector<cv::Point2f> lk_cur(n), lk_prev(n);
  for (std::size_t i = 0; i < n; ++i) {
    lk_cur[i] = pts_cur[i] / scale;
    lk_prev[i] = pts_prev[i] / scale;
  }
  std::vector<float> lk_err(opt.ego_flow_retry ? n : 0);  // the patches' mean error, for the retry
  std::vector<unsigned char> st1(n, 0), st2(n, 0);
  pts_back = lk_cur;
  // Where the IMU's motion puts each out-of-box feature with depth in the previous frame (in the
  // flow's pixels); (-1, -1) where it says nothing.
  std::vector<cv::Point2f> imu_prev;
  if (opt.fb_skip_gate_px > 0.0 && in.R_cur_prev && in.t_cur_prev && in.depth_m.size() == n) {
    imu_prev.assign(n, cv::Point2f(-1.0f, -1.0f));
    const Mat3 R_pc = in.R_cur_prev->transpose();
    const Mat3 Kinv = in.K.inverse();
    for (std::size_t i = 0; i < n; ++i) {
      if (!boxes_of[i].empty() || in.depth_m[i] <= 0) continue;
      const Vec3 X = in.depth_m[i] * (Kinv * Vec3(in.points[i].x(), in.points[i].y(), 1.0));
      const Vec3 p = in.K * (R_pc * (X - *in.t_cur_prev));
      if (p.z() <= 1e-6) continue;
      imu_prev[i] = cv::Point2f(static_cast<float>(p.x() / p.z()) / scale,
                                static_cast<float>(p.y() / p.z()) / scale);
    }
  }
  flow_by_window(cur_levels, prev_levels, windows, opt, levels,
                 std::min(opt.lk_backward_levels, levels), term, flags, lk_cur, lk_prev, pts_back,
                 st1, st2, opt.ego_flow_retry ? &lk_err : nullptr,
                 imu_prev.empty() ? nullptr : &imu_prev,
                 static_cast<float>(opt.fb_skip_gate_px) / scale, &out.flow_vouched);
  for (std::size_t i = 0; i < n; ++i) {
    pts_prev[i] = lk_prev[i] * scale;
    pts_back[i] *= scale;
  }
  std::vector<bool> valid(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    valid[i] = st1[i] && st2[i] &&
               std::hypot(pts_back[i].x - pts_cur[i].x, pts_back[i].y - pts_cur[i].y) <=
                   opt.fb_max_error_px &&
               pts_prev[i].x >= 0 && pts_prev[i].y >= 0 && pts_prev[i].x < prev_cols &&
               pts_prev[i].y < prev_rows;
    out.tracked += valid[i] ? 1 : 0;
    if (valid[i]) out.prev_points[i] = Vec2(pts_prev[i].x, pts_prev[i].y);
  }

  const cv::Matx33d Kcv = to_matx(in.K);

  // 2. Ego-motion from features outside every box.
  std::vector<cv::Point2f> cand_prev, cand_cur;
  std::vector<std::size_t> cand_idx;
  for (std::size_t i = 0; i < n; ++i) {
    if (valid[i] && boxes_of[i].empty()) {
      cand_prev.push_back(pts_prev[i]);
      cand_cur.push_back(pts_cur[i]);
      cand_idx.push_back(i);
    }
  }
  cv::Matx33d F = cv::Matx33d::zeros();
  cv::Matx33d H = cv::Matx33d::eye();
  const bool enough_background = cand_idx.size() >= 15;

  // 2b. With depth, the camera motion itself (PnP-RANSAC of current 3D points against their
  // flow positions in the previous frame) predicts where every static point must have been,
  // whatever its depth: no parallax ambiguity, no degeneracy for a still or rotating camera.
  const bool has_depth = in.depth_m.size() == n;
  std::vector<double> residual3d(n, -1.0);
  std::vector<double> far_residual(n, -1.0);  // DynamicFilterOptions::far_parallax
  std::vector<double> depth_change(n, -1.0), depth_err_m(n, -1.0);
  // The previous depth minus its prediction, each the median of a smooth 3x3 window (NaN
  // unknown): unbiased, unlike depth_err_m's reading nearest the prediction, which a point at a
  // depth step needs but which draws a slowly receding surface's error to zero.
  std::vector<double> depth_dev(n, std::numeric_limits<double>::quiet_NaN());
  std::vector<cv::Point2f> departure(n, cv::Point2f(0, 0));  // flow minus ego-motion, with depth
  bool have_3d = false;
  if (has_depth) {
    const Mat3 Kinv = in.K.inverse();
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    for (std::size_t i : cand_idx) {
      if (in.depth_m[i] <= 0) continue;
      const Vec3 X = in.depth_m[i] * (Kinv * Vec3(in.points[i].x(), in.points[i].y(), 1.0));
      obj.emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()),
                       static_cast<float>(X.z()));
      img.push_back(pts_prev[i]);
    }
    if (obj.size() >= 15) {
      cv::Mat rvec, tvec;
      bool solved = false;
      const bool prior = in.R_cur_prev && in.t_cur_prev;
      cv::Mat r_prior, t_prior;
      double gate_r = 0.0, gate_t = 0.0;
      if (prior) {
        // The prediction, as PnP's unknown: the current camera into the previous one.
        const Mat3 R_pc = in.R_cur_prev->transpose();
        const Vec3 t_pc = -(R_pc * *in.t_cur_prev);
        t_prior = (cv::Mat_<double>(3, 1) << t_pc.x(), t_pc.y(), t_pc.z());
        cv::Rodrigues(cv::Mat(to_matx(R_pc)), r_prior);
        gate_r = opt.prior_gate_sigmas * in.prior_rotation_sigma_rad;
        gate_t = std::max(opt.prior_min_translation_m,
                          opt.prior_gate_sigmas * in.prior_translation_sigma_m);
      }
      // The prediction refined on the points it explains, if enough of them: the motion below
      // takes it whatever consensus RANSAC would find (its own when they agree, the
      // prediction's when not), so RANSAC runs only where the prediction has no support.
      // How many points it explains; negative where the refinement slid off the prediction.
      const auto from_prior = [&](cv::Mat& rp, cv::Mat& tp) {
        rp = r_prior.clone();
        tp = t_prior.clone();
        const int explained = refine_motion(obj, img, Kcv, opt.prior_inlier_px, rp, tp);
        return explained >= 10 && !motion_agrees(rp, tp, r_prior, t_prior, gate_r, gate_t)
                   ? -explained
                   : explained;
      };
      // The prediction's refinement, once: tried first (prior_first) or after RANSAC disagrees.
      cv::Mat r_refined, t_refined;
      std::optional<int> explained;
      if (prior && opt.prior_first) {
        explained = from_prior(r_refined, t_refined);
        if (*explained >= 10) {
          rvec = r_refined;
          tvec = t_refined;
          solved = true;
          out.motion_from_prior = true;
        }
      }
      if (!solved) {
        std::vector<int> inliers;
        solved = cv::solvePnPRansac(obj, img, cv::Mat(Kcv), cv::noArray(), rvec, tvec, false, 100,
                                    kPnpInlierPx, 0.99, inliers, cv::SOLVEPNP_EPNP) &&
                 inliers.size() >= 10;
        // RANSAC's estimate comes from EPnP on its consensus: refine it by Levenberg-Marquardt
        // on the reprojection error of the points it explains, twice, so that its small
        // rotation and translation errors do not grow into a tail of static residuals.
        if (solved) refine_motion(obj, img, Kcv, kPnpInlierPx, rvec, tvec);
      }
      if (prior && !out.motion_from_prior &&
          (!solved || !motion_agrees(rvec, tvec, r_prior, t_prior, gate_r, gate_t))) {
        // RANSAC found another consensus than the predicted motion (or none): the points the
        // prediction explains are the world, if there are enough of them.
        if (!explained) explained = from_prior(r_refined, t_refined);
        if (std::abs(*explained) >= 10 || opt.prior_without_support) {
          // Too few points, or the refinement slid off to the other consensus: the prediction.
          const bool supported = *explained >= 10;
          rvec = supported ? r_refined : r_prior;
          tvec = supported ? t_refined : t_prior;
          solved = true;
          out.motion_from_prior = true;
        }
      }
      if (solved) {
        cv::Matx33d R;
        cv::Rodrigues(rvec, R);
        const cv::Vec3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
        have_3d = true;
        if (cv::norm(t) > 1e-3) {
          // Features without depth get the epipolar test of the same motion: measured with
          // depth, it is not bent by a mover as a five-point fit on flow alone can be, and it
          // spares that RANSAC.
          const cv::Matx33d R_cp = R.t();
          const cv::Vec3d t_cp = -(R_cp * t);
          const cv::Matx33d tx(0, -t_cp[2], t_cp[1], t_cp[2], 0, -t_cp[0], -t_cp[1], t_cp[0], 0);
          const cv::Matx33d Kinv = Kcv.inv();
          F = Kinv.t() * (tx * R_cp) * Kinv;
          out.geometry_valid = true;
        }
        if (opt.far_parallax && in.depth_range_m > 0.0)
          far_parallax_residuals(in, opt, depth_image ? in.cur_depth : nullptr, valid, pts_prev, R,
                                 t, far_residual);
        for (std::size_t i = 0; i < n; ++i) {
          if (!valid[i] || in.depth_m[i] <= 0) continue;
          const Vec3 X = in.depth_m[i] * (Kinv * Vec3(in.points[i].x(), in.points[i].y(), 1.0));
          const cv::Vec3d p = R * cv::Vec3d(X.x(), X.y(), X.z()) + t;
          if (p[2] <= 1e-6) continue;
          const double u = Kcv(0, 0) * p[0] / p[2] + Kcv(0, 2);
          const double v = Kcv(1, 1) * p[1] / p[2] + Kcv(1, 2);
          residual3d[i] = std::hypot(u - pts_prev[i].x, v - pts_prev[i].y);
          departure[i] = pts_prev[i] - cv::Point2f(static_cast<float>(u), static_cast<float>(v));
          if (in.prev_depth && !in.prev_depth->empty()) {
            // The previous depth around where the flow puts the point; the reading nearest the
            // prediction in a 3x3 window, so that a point beside a depth step is not judged by
            // the surface next to it.
            const DepthWindow prev_window = depth_window(
                *in.prev_depth, in.depth_scale, static_cast<int>(std::lround(pts_prev[i].x)),
                static_cast<int>(std::lround(pts_prev[i].y)));
            double best = -1.0;
            for (std::size_t k = 0; k < prev_window.count; ++k) {
              const double z = prev_window.z[k];
              if (best < 0 || std::fabs(z - p[2]) < std::fabs(best - p[2])) best = z;
            }
            if (best > 0) {
              depth_err_m[i] = std::fabs(best - p[2]);
              depth_change[i] = depth_err_m[i] / (p[2] * p[2]);
            }
            if (opt.depth_trail) {
              const double z_prev = smooth_depth(prev_window);
              const double z_cur =
                  depth_image
                      ? smooth_depth(depth_window(*in.cur_depth, in.depth_scale,
                                                  static_cast<int>(std::lround(in.points[i].x())),
                                                  static_cast<int>(std::lround(in.points[i].y()))))
                      : in.depth_m[i];
              if (z_prev > 0 && z_cur > 0) {
                const cv::Vec3d Xs = (z_cur / in.depth_m[i]) * cv::Vec3d(X.x(), X.y(), X.z());
                const double z_pred = (R * Xs + t)[2];
                if (z_pred > 1e-6) depth_dev[i] = z_prev - z_pred;
              }
            }
          }
        }
      }
    }
  }
  if (enough_background && !have_3d) {
    // No depth to measure the motion with: the camera is calibrated, so fit the essential
    // matrix (5 DOF, five-point RANSAC) rather than F (7 DOF): with small baselines F bends to
    // fit a large mover as well.
    std::vector<unsigned char> e_inliers;
    const cv::Mat Em = cv::findEssentialMat(cand_prev, cand_cur, cv::Mat(Kcv), cv::RANSAC, 0.999,
                                            opt.ransac_threshold_px, e_inliers);
    if (Em.rows == 3 && Em.cols == 3) {  // several solutions come stacked; the first is best
      const cv::Matx33d Kinv = Kcv.inv();
      F = Kinv.t() * cv::Matx33d(Em) * Kinv;
      out.geometry_valid = true;
    }
  }
  if (enough_background) {
    // Camera (nearly) still or only rotating: the rotation homography (IMU) or identity
    // explains the static flow. Two views cannot tell "still camera, one mover" from "camera
    // translating, background at infinity", and RANSAC then fits F to the mover too; so when
    // the rotation-compensated flow of most features is sub-pixel, the homography test decides.
    cv::Matx33d H_rot = cv::Matx33d::eye();
    if (in.R_cur_prev) {
      H_rot = to_matx(in.K * (*in.R_cur_prev) * in.K.inverse());
    }
    std::vector<double> ego_flow;
    ego_flow.reserve(cand_idx.size());
    for (std::size_t k = 0; k < cand_idx.size(); ++k) {
      ego_flow.push_back(homography_residual(H_rot, cand_prev[k], cand_cur[k]));
    }
    out.degenerate_motion = !out.geometry_valid || median_of(ego_flow) < opt.still_flow_px;
    H = H_rot;
    if (out.degenerate_motion && !in.R_cur_prev) {
      const cv::Mat Hm = cv::findHomography(cand_prev, cand_cur, cv::RANSAC, 1.0);
      if (Hm.rows == 3) H = cv::Matx33d(Hm);
    }
  }
  out.motion_3d = have_3d;
  for (std::size_t i = 0; i < n; ++i) {
    out.residual3d_px[i] = static_cast<float>(residual3d[i]);
    out.far_residual_px[i] = static_cast<float>(far_residual[i]);
    out.depth_change[i] = static_cast<float>(depth_change[i]);
  }

  if (!out.geometry_valid && !out.degenerate_motion && !have_3d) {
    // Not enough background to fit ego-motion: boxes alone decide.
    for (std::size_t i = 0; i < n; ++i) {
      if (!boxes_of[i].empty()) {
        out.labels[i] = FeatureLabel::kDynamic;
        out.reasons[i] = LabelReason::kNoGeometry;
      } else if (!valid[i]) {
        out.labels[i] = FeatureLabel::kUnknown;
        out.reasons[i] = LabelReason::kNoFlow;
      }
    }
    std::fill(out.box_moving.begin(), out.box_moving.end(), true);
    return out;
  }

  // 3. Per-feature geometric consistency.
  std::vector<double> score(n, 0.0);  // the quantity the thresholds apply to
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i]) continue;
    out.residual_px[i] = static_cast<float>(homography_residual(H, pts_prev[i], pts_cur[i]));
    if (out.geometry_valid) {
      out.epipolar_px[i] = static_cast<float>(epipolar_distance(F, pts_prev[i], pts_cur[i]));
    }
    score[i] = out.degenerate_motion ? out.residual_px[i] : out.epipolar_px[i];
  }
  // Thresholds adapt to this frame's static residual spread: one for the 3D test, one for
  // the 2D (epipolar or homography) test used where a feature has no depth.
  std::vector<double> scores2d, scores3d;
  for (std::size_t i : cand_idx) {
    // The 3D spread is taken over the PnP consensus only: with movers covering a third of the
    // view (all of them candidates when the detector is off), the raw spread would hide them.
    if (residual3d[i] >= 0 && residual3d[i] <= kPnpInlierPx) scores3d.push_back(residual3d[i]);
    scores2d.push_back(score[i]);
  }
  std::vector<double> depth_static;
  for (std::size_t i : cand_idx) {
    if (depth_change[i] >= 0 && residual3d[i] <= kPnpInlierPx)
      depth_static.push_back(depth_change[i]);
  }
  const double thr_depth = adaptive_threshold(depth_static, opt.depth_k, opt.depth_floor_per_m);
  out.depth_threshold = depth_static.empty() ? 0.0 : thr_depth;
  // Depth says the point moved: its depth error is beyond both thresholds.
  const auto depth_moved = [&](std::size_t i) {
    return depth_change[i] >= 0 && depth_change[i] > thr_depth &&
           depth_err_m[i] > opt.depth_min_change_m;
  };
  const double thr2d = adaptive_threshold(scores2d, opt.adaptive_k, opt.outside_min_threshold_px);
  const double thr3d = adaptive_threshold(scores3d, opt.adaptive_k, opt.residual3d_min_px);
  out.outside_threshold_px = have_3d ? thr3d : thr2d;
  std::vector<double> thr_out(n, thr2d);
  std::vector<double> thr_in(n, out.degenerate_motion ? thr2d : opt.epipolar_threshold_px);
  std::vector<bool> trail_moved(n, false);
  if (opt.trail && have_3d) {
    double thr_depth_dev = 0.0;
    if (opt.depth_trail) {
      std::vector<std::size_t> background;
      for (std::size_t i : cand_idx)
        if (residual3d[i] >= 0 && residual3d[i] <= kPnpInlierPx) background.push_back(i);
      thr_depth_dev = depth_departures(in, opt, background, depth_dev);
    } else {
      depth_dev.clear();
    }
    trail_moved = follow_trail(in, opt, pts_prev, residual3d, departure, thr3d, depth_dev,
                               thr_depth_dev, out.trail);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (residual3d[i] >= 0) {
      score[i] = residual3d[i];
      thr_out[i] = thr_in[i] = thr3d;
    }
  }

  // 4. Judge each box from its own features' flow: a box is moving when enough of them violate
  // the ego-motion, and its mover flow is the median flow of those.
  std::vector<cv::Point2f> mover_flow(in.boxes.size(), cv::Point2f(0, 0));
  for (std::size_t b = 0; b < in.boxes.size(); ++b) {
    int inside = 0, violating = 0;
    std::vector<double> fx, fy;
    for (std::size_t i = 0; i < n; ++i) {
      if (!valid[i] || std::find(boxes_of[i].begin(), boxes_of[i].end(), static_cast<int>(b)) ==
                           boxes_of[i].end()) {
        continue;
      }
      // Features shared with another box say little about this one; count exclusive ones.
      if (boxes_of[i].size() > 1) continue;
      ++inside;
      const bool off = score[i] > thr_in[i];
      if (off) {
        ++violating;
        fx.push_back(pts_cur[i].x - pts_prev[i].x);
        fy.push_back(pts_cur[i].y - pts_prev[i].y);
      }
      if (foreground[i] && residual3d[i] >= 0) {
        ++out.box_features[b];
        out.box_violating[b] += off ? 1 : 0;
      }
    }
    out.box_moving[b] = violating >= 3 && violating >= opt.moving_box_fraction * inside;
    if (out.box_moving[b]) {
      mover_flow[b] =
          cv::Point2f(static_cast<float>(median_of(fx)), static_cast<float>(median_of(fy)));
    }
  }

  // 5. Labels.
  for (std::size_t i = 0; i < n; ++i) {
    // Only in still parked boxes: scenery, judged as outside any box.
    const bool parked_only =
        !boxes_of[i].empty() && std::all_of(boxes_of[i].begin(), boxes_of[i].end(), [&](int b) {
          return in.boxes[static_cast<std::size_t>(b)].parked && !out.box_moving[b];
        });
    if (parked_only) {
      if (!valid[i]) {
        out.labels[i] = FeatureLabel::kUnknown;
        out.reasons[i] = LabelReason::kNoFlow;
      } else if (depth_moved(i) && score[i] <= thr_out[i]) {
        out.labels[i] = FeatureLabel::kDynamic;
        out.reasons[i] = LabelReason::kDepthChange;
      } else if (score[i] > thr_out[i]) {
        out.labels[i] = FeatureLabel::kDynamic;
        out.reasons[i] = LabelReason::kEpipolarInBox;
      } else {
        out.reasons[i] = LabelReason::kStaticInBox;
      }
      continue;
    }
    // Background seen through a box (depth known, not at the object's depth) is judged like
    // any feature outside boxes.
    const bool background_in_box =
        !boxes_of[i].empty() && !foreground[i] && in.depth_m.size() == n && in.depth_m[i] > 0;
    const bool in_box = !boxes_of[i].empty() && !background_in_box;
    // On the object's outline flow mixes both sides: the feature's own depth decides.
    if (outline[i] == 1 && !depth_moved(i)) {
      out.labels[i] = FeatureLabel::kStatic;
      out.reasons[i] = LabelReason::kOutlineBackground;
      continue;
    }
    if (outline[i] == 2 && opt.outline_no_depth_dynamic) {
      out.labels[i] = FeatureLabel::kDynamic;
      out.reasons[i] = LabelReason::kOutlineNoDepth;
      continue;
    }
    if (!valid[i]) {
      out.labels[i] = in_box ? FeatureLabel::kDynamic : FeatureLabel::kUnknown;
      out.reasons[i] = in_box ? LabelReason::kNoFlowInBox : LabelReason::kNoFlow;
      continue;
    }
    if (foreground[i]) {
      out.labels[i] = FeatureLabel::kDynamic;
      out.reasons[i] = on_rim[i] ? LabelReason::kRimOnObject : LabelReason::kForegroundInBox;
      continue;
    }
    if (far_box_no_depth[i]) {
      out.labels[i] = FeatureLabel::kDynamic;
      out.reasons[i] = LabelReason::kFarBoxNoDepth;
      continue;
    }
    if (!in_box) {
      if (far_residual[i] > thr3d) {
        out.labels[i] = FeatureLabel::kDynamic;
        out.reasons[i] = LabelReason::kFarParallax;
        continue;
      }
      if (depth_moved(i) && score[i] <= thr_out[i]) {
        out.labels[i] = FeatureLabel::kDynamic;
        out.reasons[i] = LabelReason::kDepthChange;
      } else if (score[i] > thr_out[i]) {
        if (residual3d[i] >= 0) {
          out.labels[i] = FeatureLabel::kDynamic;
          out.reasons[i] = LabelReason::kFlowResidual;
        } else if (have_3d) {
          // No depth here (an edge, a hole) while its neighbours have it: the 2D test alone is
          // too weak to throw the feature away, and too unsure to trust it.
          out.labels[i] = FeatureLabel::kUnknown;
          out.reasons[i] = LabelReason::kEpipolarOutside;
        } else {
          out.labels[i] = FeatureLabel::kDynamic;
          out.reasons[i] =
              out.degenerate_motion ? LabelReason::kFlowResidual : LabelReason::kEpipolarOutside;
        }
      }
      continue;
    }
    if (score[i] > thr_in[i]) {
      out.labels[i] = FeatureLabel::kDynamic;
      out.reasons[i] = LabelReason::kEpipolarInBox;
      continue;
    }
    // On its epipolar line: static background seen through the box, or a body part moving
    // along the line? Compare its flow with the mover flow of each moving box that holds it.
    const cv::Point2f flow = pts_cur[i] - pts_prev[i];
    for (int b : boxes_of[i]) {
      if (!out.box_moving[b]) continue;
      const cv::Point2f d = flow - mover_flow[b];
      const double tol = std::max(2.0, 0.3 * std::hypot(mover_flow[b].x, mover_flow[b].y));
      if (std::hypot(d.x, d.y) <= tol) {
        out.labels[i] = FeatureLabel::kDynamic;
        out.reasons[i] = LabelReason::kMovingBox;
        out.box_of[i] = b;
        break;
      }
    }
    if (out.labels[i] == FeatureLabel::kStatic) out.reasons[i] = LabelReason::kStaticInBox;
  }
  // Outside boxes, found static this frame, moved over its track.
  for (std::size_t i = 0; i < n; ++i) {
    if (trail_moved[i] && out.labels[i] == FeatureLabel::kStatic &&
        out.reasons[i] == LabelReason::kStaticGeometry) {
      out.labels[i] = FeatureLabel::kDynamic;
      out.reasons[i] = LabelReason::kLongBaseline;
    }
  }
  // 6. Flow that a second start at the ego-motion's prediction explains as well: the patch's
  // flow is ambiguous (a dim, noise-dominated surface whose coarse pyramid levels hold no
  // texture, where the flow from the feature's own position stops short), not a mover.
  if (opt.ego_flow_retry && have_3d) {
    std::vector<std::size_t> retry;
    std::vector<cv::Point2f> from_cur, to_prev;
    for (std::size_t i = 0; i < n; ++i) {
      if (out.reasons[i] != LabelReason::kFlowResidual || residual3d[i] < 0) continue;
      retry.push_back(i);
      from_cur.push_back(lk_cur[i]);
      to_prev.push_back((pts_prev[i] - departure[i]) / scale);
    }
    if (!retry.empty()) {
      std::vector<cv::Point2f> predicted = to_prev, back = from_cur;
      std::vector<unsigned char> st_f(retry.size(), 0), st_b(retry.size(), 0);
      std::vector<float> err(retry.size(), 0.0f);
      const int retry_levels = std::min(levels, 1);
      // Each feature with its own window, so that its error compares with its first flow's.
      std::vector<int> retry_windows(retry.size());
      for (std::size_t k = 0; k < retry.size(); ++k) retry_windows[k] = windows[retry[k]];
      flow_by_window(cur_levels, prev_levels, retry_windows, opt, retry_levels, retry_levels, term,
                     cv::OPTFLOW_USE_INITIAL_FLOW, from_cur, to_prev, back, st_f, st_b, &err);
      for (std::size_t k = 0; k < retry.size(); ++k) {
        const std::size_t i = retry[k];
        const cv::Point2f fb = back[k] * scale - pts_cur[i];
        const cv::Point2f off = (to_prev[k] - predicted[k]) * scale;
        if (st_f[k] && st_b[k] && std::hypot(fb.x, fb.y) <= opt.fb_max_error_px &&
            std::hypot(off.x, off.y) <= thr_out[i] &&
            err[k] <= opt.ego_flow_err_ratio * lk_err[i]) {
          out.labels[i] = FeatureLabel::kUnknown;
          out.reasons[i] = LabelReason::kAmbiguousFlow;
        }
      }
    }
  }
  if (opt.coherent_neighbours > 0) demote_incoherent_flow(pts_cur, departure, opt, out);
  return out;
}

void use_half_resolution_flow(DynamicFilterOptions& opt) {
  opt.lk_window = 9;
  opt.lk_window_dim = 0;
  opt.lk_base_level = 1;
  opt.lk_levels = opt.lk_backward_levels = 2;
  opt.lk_iterations = 10;
  opt.lk_epsilon_px = 0.1;
}

DynamicFilterResult combine_baselines(const DynamicFilterResult& short_baseline,
                                      const DynamicFilterResult& long_baseline,
                                      const MultiFrameOptions& opt) {
  DynamicFilterResult out = short_baseline;
  const std::size_t n = out.labels.size();
  if (long_baseline.labels.size() != n || long_baseline.residual3d_px.size() != n ||
      out.residual3d_px.size() != n) {
    return out;  // not the same points: nothing to combine
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (out.labels[i] == FeatureLabel::kDynamic) continue;
    const LabelReason lr = long_baseline.reasons[i];
    const bool long_moved =
        long_baseline.labels[i] == FeatureLabel::kDynamic &&
        (lr == LabelReason::kFlowResidual || lr == LabelReason::kEpipolarOutside ||
         lr == LabelReason::kDepthChange) &&
        long_baseline.residual3d_px[i] > opt.long_residual_px;
    if (long_moved && out.residual3d_px[i] > opt.short_residual_px) {
      out.labels[i] = FeatureLabel::kDynamic;
      out.reasons[i] = LabelReason::kLongBaseline;
    }
  }
  return out;
}

}  // namespace kestrel::dynamic
