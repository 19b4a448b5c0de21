#include "tracking/feature_extractor.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "core/grey_levels.hpp"
#include "io/cv_image.hpp"

namespace kestrel::tracking {

struct FeatureExtractor::Impl {
  cv::Ptr<cv::ORB> orb;
  cv::Ptr<cv::ORB> fallback;  // the lower FAST threshold, for images the first leaves short
  int fallback_below = 0;     // fewer candidates than this at the first threshold: the fallback

  bool short_of_candidates(const std::vector<cv::KeyPoint>& kps) const {
    return fallback && static_cast<int>(kps.size()) < fallback_below;
  }
};

FeatureExtractor::FeatureExtractor(const PinholeCamera& camera,
                                   const FeatureExtractorOptions& options)
    : camera_(camera), options_(options), impl_(std::make_unique<Impl>()) {
  if (options.target_features <= 0 || options.levels <= 0 || options.scale_factor <= 1.0f ||
      options.cell_px <= 0 || options.oversample < 1.0) {
    throw std::invalid_argument(
        "FeatureExtractorOptions: target_features, levels, cell_px must be > 0, scale_factor > 1 "
        "and oversample >= 1");
  }
  const int candidates =
      static_cast<int>(std::lround(options.target_features * options.oversample));
  const auto orb_at = [&](int fast_threshold) {
    return cv::ORB::create(candidates, options.scale_factor, options.levels,
                           /*edgeThreshold=*/19, /*firstLevel=*/0, /*WTA_K=*/2,
                           cv::ORB::HARRIS_SCORE, /*patchSize=*/31, fast_threshold);
  };
  impl_->orb = orb_at(options.fast_threshold);
  impl_->fallback_below = static_cast<int>(std::lround(candidates * options.fast_fallback_below));
  if (options.fast_threshold_fallback > 0 &&
      options.fast_threshold_fallback < options.fast_threshold) {
    impl_->fallback = orb_at(options.fast_threshold_fallback);
  }
}

FeatureExtractor::~FeatureExtractor() = default;
FeatureExtractor::FeatureExtractor(FeatureExtractor&&) noexcept = default;
FeatureExtractor& FeatureExtractor::operator=(FeatureExtractor&&) noexcept = default;

namespace {

// Picks up to `target` keypoints: first the best `quota` of every cell (round-robin by rank),
// then the best of the rest, so texture-rich cells cannot starve the others.
// `among` (optional): only these candidates compete.
std::vector<int> bucket(const std::vector<cv::KeyPoint>& kps, int width, int height, int cell_px,
                        int target, const std::vector<int>* among = nullptr) {
  const int cols = std::max(1, (width + cell_px - 1) / cell_px);
  const int rows = std::max(1, (height + cell_px - 1) / cell_px);
  std::vector<std::vector<int>> cells(static_cast<std::size_t>(cols) * rows);
  const std::size_t count = among ? among->size() : kps.size();
  for (std::size_t j = 0; j < count; ++j) {
    const int i = among ? (*among)[j] : static_cast<int>(j);
    const cv::KeyPoint& k = kps[static_cast<std::size_t>(i)];
    const int cx = std::clamp(static_cast<int>(k.pt.x) / cell_px, 0, cols - 1);
    const int cy = std::clamp(static_cast<int>(k.pt.y) / cell_px, 0, rows - 1);
    cells[static_cast<std::size_t>(cy) * cols + cx].push_back(i);
  }
  for (auto& c : cells) {
    std::sort(c.begin(), c.end(), [&](int a, int b) { return kps[a].response > kps[b].response; });
  }
  std::vector<int> chosen;
  chosen.reserve(static_cast<std::size_t>(target));
  for (std::size_t rank = 0; static_cast<int>(chosen.size()) < target; ++rank) {
    // One round takes the rank-th best of every cell that has one, best responses first.
    std::vector<int> round;
    for (const auto& c : cells) {
      if (rank < c.size()) round.push_back(c[rank]);
    }
    if (round.empty()) break;
    std::sort(round.begin(), round.end(),
              [&](int a, int b) { return kps[a].response > kps[b].response; });
    for (int i : round) {
      if (static_cast<int>(chosen.size()) >= target) break;
      chosen.push_back(i);
    }
  }
  return chosen;
}

// Bucketing with movers' regions apart: the candidates there keep the share that bucketing
// over the whole image gives them, and the rest of the image gets the whole target of its
// own, so a crowd filling half the view no longer takes half the scenery's features. The
// features in the movers' regions are the same as without them; the others are a superset.
std::vector<int> bucket_apart(const std::vector<cv::KeyPoint>& kps, const cv::Mat& apart, int width,
                              int height, int cell_px, int target) {
  std::vector<int> chosen = bucket(kps, width, height, cell_px, target);
  const auto in_apart = [&](int i) {
    const cv::Point2f& p = kps[static_cast<std::size_t>(i)].pt;
    const int u = std::clamp(static_cast<int>(p.x), 0, apart.cols - 1);
    const int v = std::clamp(static_cast<int>(p.y), 0, apart.rows - 1);
    return apart.at<std::uint8_t>(v, u) != 0;
  };
  std::vector<int> outside;
  for (int i = 0; i < static_cast<int>(kps.size()); ++i) {
    if (!in_apart(i)) outside.push_back(i);
  }
  if (outside.size() == kps.size()) return chosen;
  std::vector<int> out = bucket(kps, width, height, cell_px, target, &outside);
  for (int i : chosen) {
    if (in_apart(i)) out.push_back(i);
  }
  return out;
}

// OpenCV's ORB reports a level-L corner at (x_L, y_L) * scale^L, but its pyramid is built
// with cv::resize, which maps pixel centres: x_0 = (x_L + 0.5) * W / W_L - 0.5, with W_L the
// level's rounded width. The difference is a level-dependent offset of up to 1.5 px plus a
// scale error of up to 0.2% (measured by flipping a frame: ORB's positions are not mirror-
// symmetric, these are). Matched across frames at different levels, that offset is pose error.
Vec2 level0_position(const cv::KeyPoint& k, int width, int height, float scale_factor) {
  if (k.octave <= 0) return Vec2(k.pt.x, k.pt.y);
  const double s = std::pow(static_cast<double>(scale_factor), k.octave);
  // The level sizes as OpenCV computes them: cvRound(size / scale^L).
  const int wl = cvRound(width / s);
  const int hl = cvRound(height / s);
  const double xl = k.pt.x / s;
  const double yl = k.pt.y / s;
  return Vec2((xl + 0.5) * width / wl - 0.5, (yl + 0.5) * height / hl - 0.5);
}

// Corners often sit on a silhouette, where the pixel under the keypoint may belong to either
// surface: a map point seeded there can be metres off. A corner whose 3x3 neighbourhood spans
// a depth step (or a hole) gets no depth and is tracked as a bearing only.
constexpr int kOutlineRadiusPx = 3;
static_assert(kOutlineRadiusPx > 0);

bool depth_is_smooth(const Image& depth, int u, int v, double raw, double ratio) {
  if (ratio <= 0.0) return true;
  const double tol = ratio * raw;
  for (int dv = -1; dv <= 1; ++dv) {
    const int y = std::clamp(v + dv, 0, depth.height - 1);
    const std::uint16_t* row = depth.row<std::uint16_t>(y);
    for (int du = -1; du <= 1; ++du) {
      const int x = std::clamp(u + du, 0, depth.width - 1);
      if (row[x] == 0 || std::abs(row[x] - raw) > tol) return false;
    }
  }
  return true;
}

// Whether an in-range reading lies at (u, v) or `radius` pixels from it along a row, a column
// or a diagonal (a 3x3 grid of samples): a keypoint without depth of its own next to one sits on an
// object's outline, where sensors leave holes, not beyond the sensor's range.
bool depth_reading_near(const Image& depth, int u, int v, int radius, double min_raw,
                        double max_raw) {
  const int step = std::max(1, radius);
  for (int dv = -radius; dv <= radius; dv += step) {
    const int y = std::clamp(v + dv, 0, depth.height - 1);
    const std::uint16_t* row = depth.row<std::uint16_t>(y);
    for (int du = -radius; du <= radius; du += step) {
      const int x = std::clamp(u + du, 0, depth.width - 1);
      if (row[x] >= min_raw && row[x] <= max_raw) return true;
    }
  }
  return false;
}

// A dim, low-contrast image (a dark corridor, an underexposed frame) is stretched linearly
// so that its 1st..99th percentile spans the 8-bit range: FAST's fixed threshold then asks
// the same relative contrast of it as of a well-lit one. Well-exposed images are left exactly
// as they are (their corners and descriptors do not change).
cv::Mat stretch_if_dim(const cv::Mat& grey, const FeatureExtractorOptions& o) {
  const GreyRange range = grey_range(grey.ptr<std::uint8_t>(0), grey.cols, grey.rows, grey.step);
  const int lo = range.lo;
  const double gain = std::min(o.dim_max_gain, 255.0 / std::max(1, range.spread()));
  if (gain < o.dim_min_gain) return grey;
  cv::Mat out;
  grey.convertTo(out, CV_8U, gain, -gain * lo);
  return out;
}

void check_same_size(const Image& a, const Image& b, const char* what) {
  if (a.width != b.width || a.height != b.height) {
    throw std::invalid_argument(std::string("FeatureExtractor: ") + what + " is " +
                                std::to_string(b.width) + "x" + std::to_string(b.height) +
                                ", image is " + std::to_string(a.width) + "x" +
                                std::to_string(a.height));
  }
}

}  // namespace

FrameFeatures FeatureExtractor::extract(const Image& image, const Image* ignore, const Image* depth,
                                        double depth_scale, Timestamp t,
                                        const Image* movers) const {
  if (image.empty() || image.type != PixelType::kU8 ||
      (image.channels != 1 && image.channels != 3)) {
    throw std::invalid_argument("FeatureExtractor: image must be 8-bit grey or BGR");
  }
  cv::Mat grey = io::as_mat(image);
  if (image.channels == 3) {
    cv::Mat g;
    cv::cvtColor(grey, g, cv::COLOR_BGR2GRAY);
    grey = g;
  }
  if (options_.dim_max_gain > 1.0) grey = stretch_if_dim(grey, options_);
  cv::Mat mask;
  if (ignore && !ignore->empty()) {
    check_same_size(image, *ignore, "ignore mask");
    if (ignore->type != PixelType::kU8 || ignore->channels != 1) {
      throw std::invalid_argument("FeatureExtractor: ignore mask must be 8-bit, 1 channel");
    }
    // OpenCV's mask selects where to detect; ours says where not to.
    mask = io::as_mat(*ignore) == 0;
  }
  if (depth && !depth->empty()) {
    check_same_size(image, *depth, "depth");
    if (depth->type != PixelType::kU16 || depth->channels != 1) {
      throw std::invalid_argument("FeatureExtractor: depth must be 16-bit, 1 channel");
    }
    if (!(depth_scale > 0.0)) throw std::invalid_argument("FeatureExtractor: depth_scale <= 0");
  }
  cv::Mat apart;
  if (movers && !movers->empty()) {
    check_same_size(image, *movers, "movers mask");
    if (movers->type != PixelType::kU8 || movers->channels != 1) {
      throw std::invalid_argument("FeatureExtractor: movers mask must be 8-bit, 1 channel");
    }
    apart = io::as_mat(*movers);
  }
  const auto choose = [&](const std::vector<cv::KeyPoint>& candidates) {
    return apart.empty() ? bucket(candidates, image.width, image.height, options_.cell_px,
                                  options_.target_features)
                         : bucket_apart(candidates, apart, image.width, image.height,
                                        options_.cell_px, options_.target_features);
  };

  // Describing only the chosen keypoints: ORB's compute() rebuilds and blurs the pyramid, but
  // that costs less than describing the 2000 candidates bucketing drops. compute() returns the
  // keypoints grouped by level with their coordinates scaled down and up again, so each row is
  // put back at its keypoint's place in the bucketing order, beside the keypoint as detected:
  // the features come out exactly as describing every candidate gives them (tests/tracking).
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  std::vector<int> chosen;
  if (options_.describe_chosen_only) {
    impl_->orb->detect(grey, kps, mask);
    if (impl_->short_of_candidates(kps)) {
      kps.clear();
      impl_->fallback->detect(grey, kps, mask);
    }
    chosen = choose(kps);
    std::vector<cv::KeyPoint> described;
    described.reserve(chosen.size());
    for (std::size_t i = 0; i < chosen.size(); ++i) {
      described.push_back(kps[static_cast<std::size_t>(chosen[i])]);
      described.back().class_id = static_cast<int>(i);
    }
    cv::Mat rows;
    impl_->orb->compute(grey, described, rows);
    // compute() drops keypoints too close to the border to describe; detect() returns none
    // such. Should one come anyway, it is dropped from the chosen too.
    std::vector<int> row_of(chosen.size(), -1);
    for (std::size_t r = 0; r < described.size(); ++r) {
      row_of[static_cast<std::size_t>(described[r].class_id)] = static_cast<int>(r);
    }
    std::vector<int> kept;
    desc.create(static_cast<int>(described.size()), rows.cols, rows.type());
    for (std::size_t i = 0; i < chosen.size(); ++i) {
      if (row_of[i] < 0) continue;
      rows.row(row_of[i]).copyTo(desc.row(static_cast<int>(kept.size())));
      kept.push_back(chosen[i]);
    }
    chosen = std::move(kept);
  } else {
    impl_->orb->detectAndCompute(grey, mask, kps, desc);
    if (impl_->short_of_candidates(kps)) {
      kps.clear();
      impl_->fallback->detectAndCompute(grey, mask, kps, desc);
    }
    chosen = choose(kps);
  }
  std::vector<cv::KeyPoint> selected;
  selected.reserve(chosen.size());
  for (int i : chosen) selected.push_back(kps[static_cast<std::size_t>(i)]);

  FrameFeatures f;
  f.t = t;
  f.width = image.width;
  f.height = image.height;
  f.scale_factor = options_.scale_factor;
  f.levels = options_.levels;
  const std::size_t n = selected.size();
  f.keypoints.resize(n);
  f.descriptors.resize(n);
  f.depth.assign(n, 0.0);
  f.sensor_depth.assign(n, 0.0);
  if (depth && !depth->empty()) f.on_depth_step.assign(n, 0);
  f.points_c.assign(n, Vec3::Zero());
  f.status.assign(n, FeatureStatus::kStatic);
  const bool distorted = camera_.model != DistortionModel::kNone;
  for (std::size_t i = 0; i < n; ++i) {
    const cv::KeyPoint& k = selected[i];
    Keypoint& out = f.keypoints[i];
    out.px = level0_position(k, image.width, image.height, options_.scale_factor);
    out.angle = k.angle;
    out.response = k.response;
    out.level = k.octave;
    const Vec3 ray = distorted ? camera_.unproject(out.px)
                               : Vec3((out.px.x() - camera_.cx) / camera_.fx,
                                      (out.px.y() - camera_.cy) / camera_.fy, 1.0);
    out.un = Vec2(camera_.fx * ray.x() + camera_.cx, camera_.fy * ray.y() + camera_.cy);
    f.descriptors[i] = OrbDescriptor::from_bytes(
        desc.ptr<std::uint8_t>(options_.describe_chosen_only ? static_cast<int>(i) : chosen[i]));
    if (depth && !depth->empty()) {
      const int u = std::clamp(static_cast<int>(std::lround(out.px.x())), 0, depth->width - 1);
      const int v = std::clamp(static_cast<int>(std::lround(out.px.y())), 0, depth->height - 1);
      const double z = depth->row<std::uint16_t>(v)[u] / depth_scale;
      if (z >= options_.min_depth && z <= options_.max_depth) f.sensor_depth[i] = z;
      if (z >= options_.min_depth && z <= options_.max_depth &&
          depth_is_smooth(*depth, u, v, z * depth_scale, options_.edge_depth_ratio)) {
        f.depth[i] = z;
        f.points_c[i] = z * ray;
      } else if (depth_reading_near(*depth, u, v, kOutlineRadiusPx,
                                    options_.min_depth * depth_scale,
                                    options_.max_depth * depth_scale)) {
        f.on_depth_step[i] = 1;
      }
    }
  }
  f.build_grid();
  return f;
}

}  // namespace kestrel::tracking
