#include "tracking/corner_tracks.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <stdexcept>

#include "io/cv_image.hpp"

namespace kestrel::tracking {
namespace {

bool inside_any(const std::vector<PixelBox>& boxes, double x, double y) {
  return std::any_of(boxes.begin(), boxes.end(),
                     [&](const PixelBox& b) { return b.contains(x, y); });
}

// Metres at pixel (u, v), or 0 where the 3x3 patch around it is incomplete or straddles a depth
// edge: a corner on an outline takes its depth from either side.
double patch_depth(const cv::Mat& depth, double scale, int u, int v) {
  if (u < 1 || v < 1 || u >= depth.cols - 1 || v >= depth.rows - 1) return 0.0;
  std::uint16_t lo = 0xffff, hi = 0;
  for (int dv = -1; dv <= 1; ++dv) {
    const auto* row = depth.ptr<std::uint16_t>(v + dv);
    for (int du = -1; du <= 1; ++du) {
      const std::uint16_t d = row[u + du];
      if (d == 0) return 0.0;
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  }
  const double z = depth.at<std::uint16_t>(v, u) / scale;
  return (hi - lo) / scale <= 0.02 * z + 0.01 ? z : 0.0;
}

cv::Mat smoothed(const Image& gray, double sigma, const char* which) {
  if (gray.empty() || gray.channels != 1 || gray.type != PixelType::kU8) {
    throw std::invalid_argument(std::string("follow_corners: ") + which +
                                " must be an 8-bit single-channel image");
  }
  cv::Mat out;
  if (sigma > 0.0) {
    cv::GaussianBlur(io::as_mat(gray), out, cv::Size(0, 0), sigma);
  } else {
    out = io::as_mat(gray);
  }
  return out;
}

}  // namespace

CornerTracks follow_corners(const Image& ref_gray, const Image& ref_depth, double ref_scale,
                            const Image& cur_gray, const PinholeCamera& camera,
                            const CornerTrackOptions& options,
                            const std::vector<PixelBox>& exclude) {
  if (ref_depth.empty() || ref_depth.type != PixelType::kU16 || ref_depth.channels != 1 ||
      ref_depth.width != ref_gray.width || ref_depth.height != ref_gray.height ||
      !(ref_scale > 0.0)) {
    throw std::invalid_argument(
        "follow_corners: ref_depth must be a 16-bit single-channel image of ref_gray's size "
        "with a positive scale");
  }
  const cv::Mat a = smoothed(ref_gray, options.blur_sigma, "ref_gray");
  const cv::Mat b = smoothed(cur_gray, options.blur_sigma, "cur_gray");
  if (a.size() != b.size()) {
    throw std::invalid_argument("follow_corners: ref_gray and cur_gray differ in size");
  }
  const cv::Mat depth = io::as_mat(ref_depth);

  // Movers' boxes are masked before the corners are chosen, not after: the quality bar is a
  // share of the strongest corner, and a walker's outline against a dark wall set it above
  // every blotch of the wall (corridor-dark, seed 1, 24.7 s: 60 corners instead of 300).
  cv::Mat mask;
  if (!exclude.empty()) {
    mask = cv::Mat(a.size(), CV_8U, cv::Scalar(255));
    for (const PixelBox& box : exclude) {
      const cv::Rect r(cv::Point(static_cast<int>(std::floor(box.x_min)),
                                 static_cast<int>(std::floor(box.y_min))),
                       cv::Point(static_cast<int>(std::ceil(box.x_max)) + 1,
                                 static_cast<int>(std::ceil(box.y_max)) + 1));
      mask(r & cv::Rect(0, 0, mask.cols, mask.rows)).setTo(0);
    }
  }
  std::vector<cv::Point2f> found;
  cv::goodFeaturesToTrack(a, found, options.max_corners, options.corner_quality,
                          options.corner_min_distance_px, mask, options.corner_block_px);
  std::vector<cv::Point2f> ref_px;
  std::vector<Vec3> ref_points;
  for (const cv::Point2f& p : found) {
    const double z = patch_depth(depth, ref_scale, static_cast<int>(std::lround(p.x)),
                                 static_cast<int>(std::lround(p.y)));
    if (!(z >= options.min_depth_m && z <= options.max_depth_m)) continue;
    ref_px.push_back(p);
    ref_points.push_back(camera.unproject(Vec2(p.x, p.y)) * z);
  }
  CornerTracks result;
  result.corners = static_cast<int>(ref_px.size());
  if (ref_px.empty()) return result;

  const cv::Size window(options.flow_window_px, options.flow_window_px);
  const cv::TermCriteria stop(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 20, 0.03);
  std::vector<cv::Point2f> cur_px, back_px;
  std::vector<unsigned char> forward_ok, backward_ok;
  std::vector<float> err;
  cv::calcOpticalFlowPyrLK(a, b, ref_px, cur_px, forward_ok, err, window, options.flow_levels,
                           stop);
  back_px = ref_px;
  cv::calcOpticalFlowPyrLK(b, a, cur_px, back_px, backward_ok, err, window, options.flow_levels,
                           stop, cv::OPTFLOW_USE_INITIAL_FLOW);
  for (std::size_t i = 0; i < ref_px.size(); ++i) {
    if (!forward_ok[i] || !backward_ok[i]) continue;
    const double fb = std::hypot(back_px[i].x - ref_px[i].x, back_px[i].y - ref_px[i].y);
    if (!(fb <= options.max_forward_backward_px)) continue;
    const cv::Point2f& q = cur_px[i];
    if (!camera.in_image(Vec2(q.x, q.y)) || inside_any(exclude, q.x, q.y)) continue;
    const Vec3 ray = camera.unproject(Vec2(q.x, q.y));
    result.tracks.push_back(
        {ref_points[i], Vec2(camera.fx * ray.x() + camera.cx, camera.fy * ray.y() + camera.cy)});
  }
  return result;
}

}  // namespace kestrel::tracking
