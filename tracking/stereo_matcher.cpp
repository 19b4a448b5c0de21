#include "tracking/stereo_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "io/cv_image.hpp"

namespace kestrel::tracking {

struct StereoMatcher::Impl {
  explicit Impl(FeatureExtractor right) : right_extractor(std::move(right)) {}
  FeatureExtractor right_extractor;
  Mat3 R1;  // left camera -> rectified left
  Mat3 R2;  // right camera -> rectified right
  double cx = 0.0, cy = 0.0;
  cv::Mat map_left_1, map_left_2, map_right_1, map_right_2;
};

namespace {

cv::Mat camera_matrix(const PinholeCamera& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
}

cv::Mat distortion(const PinholeCamera& c) {
  if (c.model == DistortionModel::kEquidistant) {
    return (cv::Mat_<double>(4, 1) << c.dist[0], c.dist[1], c.dist[2], c.dist[3]);
  }
  if (c.model == DistortionModel::kRadTan) {
    return (cv::Mat_<double>(5, 1) << c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]);
  }
  return cv::Mat::zeros(5, 1, CV_64F);
}

Mat3 to_eigen(const cv::Mat& m) {
  Mat3 r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r(i, j) = m.at<double>(i, j);
  }
  return r;
}

cv::Mat grey_mat(const Image& image, const PinholeCamera& cam, const char* which) {
  if (image.empty() || image.type != PixelType::kU8 ||
      (image.channels != 1 && image.channels != 3)) {
    throw std::invalid_argument(std::string("StereoMatcher: ") + which +
                                " image must be 8-bit grey or BGR");
  }
  if (image.width != cam.width || image.height != cam.height) {
    throw std::invalid_argument(std::string("StereoMatcher: ") + which + " image is " +
                                std::to_string(image.width) + "x" + std::to_string(image.height) +
                                ", calibration says " + std::to_string(cam.width) + "x" +
                                std::to_string(cam.height));
  }
  cv::Mat m = io::as_mat(image);
  if (image.channels == 3) {
    cv::Mat g;
    cv::cvtColor(m, g, cv::COLOR_BGR2GRAY);
    return g;
  }
  return m;
}

// Images of the rectified pyramid, built on demand: SAD refinement needs only a few levels.
class Pyramid {
 public:
  Pyramid(cv::Mat base, double scale_factor, int levels)
      : scale_factor_(scale_factor), levels_(static_cast<std::size_t>(levels)) {
    levels_[0] = std::move(base);
  }
  const cv::Mat& level(int l) {
    cv::Mat& m = levels_[static_cast<std::size_t>(l)];
    if (m.empty()) {
      const double s = std::pow(scale_factor_, l);
      const cv::Size size(static_cast<int>(std::lround(levels_[0].cols / s)),
                          static_cast<int>(std::lround(levels_[0].rows / s)));
      cv::resize(levels_[0], m, size, 0, 0, cv::INTER_LINEAR);
    }
    return m;
  }

 private:
  double scale_factor_;
  std::vector<cv::Mat> levels_;
};

// Sub-pixel position in the right level image of the left patch centred at (ul, v), starting
// from ur0; NaN when the minimum lies on the search border or the parabola is degenerate.
// *sad receives the best patch difference.
double refine_sad(const cv::Mat& left, const cv::Mat& right, int ul, int v, int ur0, int w,
                  int search, float* sad) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (v - w < 0 || v + w >= left.rows || ul - w < 0 || ul + w >= left.cols ||
      ur0 - search - w < 0 || ur0 + search + w >= right.cols) {
    return nan;
  }
  const float centre_l = left.at<std::uint8_t>(v, ul);
  std::vector<float> dist(static_cast<std::size_t>(2 * search + 1));
  float best = std::numeric_limits<float>::max();
  int best_k = 0;
  for (int k = -search; k <= search; ++k) {
    const float centre_r = right.at<std::uint8_t>(v, ur0 + k);
    float s = 0.0f;
    for (int dy = -w; dy <= w; ++dy) {
      const std::uint8_t* lrow = left.ptr<std::uint8_t>(v + dy);
      const std::uint8_t* rrow = right.ptr<std::uint8_t>(v + dy);
      for (int dx = -w; dx <= w; ++dx) {
        s += std::abs((lrow[ul + dx] - centre_l) - (rrow[ur0 + k + dx] - centre_r));
      }
    }
    dist[static_cast<std::size_t>(k + search)] = s;
    if (s < best) {
      best = s;
      best_k = k;
    }
  }
  if (best_k == -search || best_k == search) return nan;
  const std::size_t b = static_cast<std::size_t>(best_k + search);
  const double d1 = dist[b - 1], d2 = dist[b], d3 = dist[b + 1];
  const double denom = 2.0 * (d1 + d3 - 2.0 * d2);
  if (!(denom > 0.0)) return nan;
  const double delta = (d1 - d3) / denom;
  if (delta < -1.0 || delta > 1.0) return nan;
  *sad = best;
  return ur0 + best_k + delta;
}

}  // namespace

StereoMatcher::StereoMatcher(const StereoRig& rig, const FeatureExtractorOptions& features,
                             const StereoMatcherOptions& options)
    : rig_(rig), features_(features), options_(options) {
  if (rig.left.width != rig.right.width || rig.left.height != rig.right.height) {
    throw std::invalid_argument("StereoMatcher: left and right images differ in size");
  }
  if (rig.left.model != rig.right.model) {
    throw std::invalid_argument("StereoMatcher: left and right distortion models differ");
  }
  FeatureExtractorOptions right_opt = features;
  right_opt.target_features = options.right_features;
  right_opt.oversample = options.right_oversample;
  impl_ = std::make_unique<Impl>(FeatureExtractor(rig.right, right_opt));

  // OpenCV wants the right camera's pose relative to the left: x_right = R x_left + T.
  const SE3 T_right_left = rig.T_left_right.inverse();
  cv::Mat R(3, 3, CV_64F), T(3, 1, CV_64F);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) R.at<double>(i, j) = T_right_left.rotation()(i, j);
    T.at<double>(i) = T_right_left.translation()(i);
  }
  const cv::Size size(rig.left.width, rig.left.height);
  const cv::Mat K1 = camera_matrix(rig.left), K2 = camera_matrix(rig.right);
  const cv::Mat D1 = distortion(rig.left), D2 = distortion(rig.right);
  cv::Mat R1, R2, P1, P2, Q;
  if (rig.left.model == DistortionModel::kEquidistant) {
    cv::fisheye::stereoRectify(K1, D1, K2, D2, size, R, T, R1, R2, P1, P2, Q,
                               cv::CALIB_ZERO_DISPARITY, size, 0.0, 1.0);
    cv::fisheye::initUndistortRectifyMap(K1, D1, R1, P1, size, CV_16SC2, impl_->map_left_1,
                                         impl_->map_left_2);
    cv::fisheye::initUndistortRectifyMap(K2, D2, R2, P2, size, CV_16SC2, impl_->map_right_1,
                                         impl_->map_right_2);
  } else {
    cv::stereoRectify(K1, D1, K2, D2, size, R, T, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY, 0.0);
    cv::initUndistortRectifyMap(K1, D1, R1, P1, size, CV_16SC2, impl_->map_left_1,
                                impl_->map_left_2);
    cv::initUndistortRectifyMap(K2, D2, R2, P2, size, CV_16SC2, impl_->map_right_1,
                                impl_->map_right_2);
  }
  if (std::abs(P2.at<double>(1, 3)) > std::abs(P2.at<double>(0, 3))) {
    throw std::invalid_argument("StereoMatcher: vertical stereo rigs are not supported");
  }
  impl_->R1 = to_eigen(R1);
  impl_->R2 = to_eigen(R2);
  f_ = P1.at<double>(0, 0);
  impl_->cx = P1.at<double>(0, 2);
  impl_->cy = P1.at<double>(1, 2);
  baseline_ = -P2.at<double>(0, 3) / f_;
  if (!(baseline_ > 0.0) || !std::isfinite(f_)) {
    throw std::invalid_argument(
        "StereoMatcher: the right camera must lie to the right of the left one (baseline " +
        std::to_string(baseline_) + " m)");
  }
}

StereoMatcher::~StereoMatcher() = default;
StereoMatcher::StereoMatcher(StereoMatcher&&) noexcept = default;
StereoMatcher& StereoMatcher::operator=(StereoMatcher&&) noexcept = default;

StereoStats StereoMatcher::compute_depth(FrameFeatures& left, const Image& left_image,
                                         const Image& right_image) const {
  const cv::Mat grey_l = grey_mat(left_image, rig_.left, "left");
  const cv::Mat grey_r = grey_mat(right_image, rig_.right, "right");
  StereoStats stats;

  // Right features, moved into the rectified frame.
  const FrameFeatures right = impl_->right_extractor.extract(right_image);
  const int rows = rig_.left.height;
  std::vector<std::vector<int>> by_row(static_cast<std::size_t>(rows));
  std::vector<double> right_u(right.size(), 0.0);
  for (std::size_t j = 0; j < right.size(); ++j) {
    const Vec2& un = right.keypoints[j].un;
    const Vec3 ray((un.x() - rig_.right.cx) / rig_.right.fx,
                   (un.y() - rig_.right.cy) / rig_.right.fy, 1.0);
    const Vec3 p = impl_->R2 * ray;
    if (p.z() <= 1e-6) continue;
    right_u[j] = f_ * p.x() / p.z() + impl_->cx;
    const double v = f_ * p.y() / p.z() + impl_->cy;
    const double r = options_.row_band_px * right.level_scale(right.keypoints[j].level);
    const int lo = std::max(0, static_cast<int>(std::floor(v - r)));
    const int hi = std::min(rows - 1, static_cast<int>(std::ceil(v + r)));
    for (int y = lo; y <= hi; ++y)
      by_row[static_cast<std::size_t>(y)].push_back(static_cast<int>(j));
  }

  cv::Mat rect_l, rect_r;
  cv::remap(grey_l, rect_l, impl_->map_left_1, impl_->map_left_2, cv::INTER_LINEAR);
  cv::remap(grey_r, rect_r, impl_->map_right_1, impl_->map_right_2, cv::INTER_LINEAR);
  Pyramid pyr_l(rect_l, left.scale_factor, left.levels);
  Pyramid pyr_r(rect_r, left.scale_factor, left.levels);

  const double min_disparity = f_ * baseline_ / (options_.max_depth_baselines * baseline_);
  const double max_disparity = f_ * baseline_ / options_.min_depth;
  struct Found {
    std::size_t feature;
    double u_l, v_l, disparity;
    float sad;
  };
  std::vector<Found> found;
  for (std::size_t i = 0; i < left.size(); ++i) {
    if (left.has_depth(i)) continue;
    const Keypoint& kp = left.keypoints[i];
    const Vec3 ray((kp.un.x() - rig_.left.cx) / rig_.left.fx,
                   (kp.un.y() - rig_.left.cy) / rig_.left.fy, 1.0);
    const Vec3 p = impl_->R1 * ray;
    if (p.z() <= 1e-6) continue;
    const double ul = f_ * p.x() / p.z() + impl_->cx;
    const double vl = f_ * p.y() / p.z() + impl_->cy;
    const int row = static_cast<int>(std::lround(vl));
    if (row < 0 || row >= rows) continue;
    ++stats.candidates;
    int best = options_.max_distance + 1;
    int best_j = -1;
    for (int j : by_row[static_cast<std::size_t>(row)]) {
      const auto& rk = right.keypoints[static_cast<std::size_t>(j)];
      if (std::abs(rk.level - kp.level) > 1) continue;
      const double d = ul - right_u[static_cast<std::size_t>(j)];
      if (d < 0.0 || d > max_disparity) continue;
      const int h = hamming(left.descriptors[i], right.descriptors[static_cast<std::size_t>(j)]);
      if (h < best) {
        best = h;
        best_j = j;
      }
    }
    if (best_j < 0 || best > options_.max_distance) continue;

    const double s = left.level_scale(kp.level);
    const int ul_l = static_cast<int>(std::lround(ul / s));
    const int v_l = static_cast<int>(std::lround(vl / s));
    const int ur0_l = static_cast<int>(std::lround(right_u[static_cast<std::size_t>(best_j)] / s));
    float sad = 0.0f;
    const double ur_l = refine_sad(pyr_l.level(kp.level), pyr_r.level(kp.level), ul_l, v_l, ur0_l,
                                   options_.sad_half_window, options_.sad_search, &sad);
    if (!std::isfinite(ur_l)) continue;
    // The patch was centred on the rounded left position: measure disparity from there.
    const double disparity = (ul_l - ur_l) * s;
    if (disparity < min_disparity || disparity > max_disparity) continue;
    found.push_back({i, ul, vl, disparity, sad});
  }

  // ORB-SLAM's SAD outlier test: drop matches far worse than the typical one.
  if (!found.empty()) {
    std::vector<float> sads;
    sads.reserve(found.size());
    for (const Found& x : found) sads.push_back(x.sad);
    std::nth_element(sads.begin(), sads.begin() + static_cast<long>(sads.size() / 2), sads.end());
    const double limit = options_.sad_outlier_factor * sads[sads.size() / 2];
    for (const Found& x : found) {
      if (x.sad > limit) continue;
      const double z = f_ * baseline_ / x.disparity;
      const Vec3 p_rect((x.u_l - impl_->cx) * z / f_, (x.v_l - impl_->cy) * z / f_, z);
      const Vec3 p_c = impl_->R1.transpose() * p_rect;
      if (!(p_c.z() > 0.0) || !p_c.allFinite()) continue;
      left.depth[x.feature] = p_c.z();
      left.points_c[x.feature] = p_c;
      ++stats.matched;
    }
  }
  return stats;
}

}  // namespace kestrel::tracking
