#include "tracking/feature_extractor.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>
#include <tuple>

#include "io/image_io.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::tracking {
namespace {

PinholeCamera tum_camera() {
  PinholeCamera c;
  c.fx = 535.4;
  c.fy = 539.2;
  c.cx = 320.1;
  c.cy = 247.6;
  return c;
}

RgbdFrame tum_frame() {
  RgbdFrame f;
  f.color = io::load_image(test::shared_data("tum_fr3/frame/rgb_1341846313.592026.png").string(),
                           io::ImageKind::kColor);
  f.depth = io::load_image(test::shared_data("tum_fr3/frame/depth_1341846313.592088.png").string(),
                           io::ImageKind::kDepth);
  f.depth_scale = 5000.0;
  return f;
}

// The frame with every colour value v replaced by level(v), rounded and clamped to 0..255.
template <typename Level>
RgbdFrame with_grey_levels(const RgbdFrame& frame, Level level) {
  RgbdFrame out = frame;
  out.color =
      Image::allocate(frame.color.width, frame.color.height, frame.color.channels, PixelType::kU8);
  for (int y = 0; y < frame.color.height; ++y) {
    const std::uint8_t* in = frame.color.row<std::uint8_t>(y);
    std::uint8_t* o = out.color.row<std::uint8_t>(y);
    for (int x = 0; x < frame.color.width * frame.color.channels; ++x) {
      o[x] = static_cast<std::uint8_t>(std::clamp(std::lround(level(double(in[x]))), 0L, 255L));
    }
  }
  return out;
}

TEST(FeatureExtractor, TargetCountAndSpreadOnRealFrame) {
  const FeatureExtractor ex(tum_camera());
  const FrameFeatures f = ex.extract(tum_frame());
  EXPECT_GE(f.size(), 900u);
  EXPECT_LE(f.size(), 1000u);
  // Spread: features in at least 85% of an 8x6 grid of 80-pixel cells.
  std::set<int> cells;
  for (const auto& k : f.keypoints) {
    cells.insert(static_cast<int>(k.px.y() / 80) * 8 + static_cast<int>(k.px.x() / 80));
  }
  std::cerr << "occupied cells: " << cells.size() << "\n";
  EXPECT_GE(cells.size(), 41u);
  EXPECT_EQ(f.descriptors.size(), f.size());
  EXPECT_EQ(f.status.size(), f.size());
  for (auto s : f.status) EXPECT_EQ(s, FeatureStatus::kStatic);
}

// The extractor describes only the keypoints it keeps; its features must be exactly those of
// describing every candidate in one pass: same order, positions, angles, levels, descriptor
// bytes, depth.
TEST(FeatureExtractor, DescribingTheChosenOnlyGivesTheOnePassFeatures) {
  FeatureExtractorOptions one_pass;
  one_pass.describe_chosen_only = false;
  const RgbdFrame frame = tum_frame();
  const FrameFeatures a = FeatureExtractor(tum_camera()).extract(frame);
  const FrameFeatures b = FeatureExtractor(tum_camera(), one_pass).extract(frame);
  ASSERT_GE(a.size(), 900u);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.keypoints[i].px, b.keypoints[i].px) << "feature " << i;
    EXPECT_EQ(a.keypoints[i].angle, b.keypoints[i].angle) << "feature " << i;
    EXPECT_EQ(a.keypoints[i].level, b.keypoints[i].level) << "feature " << i;
    EXPECT_EQ(a.descriptors[i], b.descriptors[i]) << "feature " << i;
    EXPECT_EQ(a.depth[i], b.depth[i]) << "feature " << i;
  }
}

// The share of `a`'s keypoints that `b` has within a pixel.
double keypoint_overlap(const FrameFeatures& a, const FrameFeatures& b) {
  int hit = 0;
  for (const auto& ka : a.keypoints) {
    for (const auto& kb : b.keypoints) {
      if ((ka.px - kb.px).norm() <= 1.0) {
        ++hit;
        break;
      }
    }
  }
  return a.keypoints.empty() ? 0.0 : double(hit) / double(a.keypoints.size());
}

// A frame taken at a third of the exposure (a dark corridor) should give the corners of the
// well-lit one: with the dim-image stretch it does; FAST's fixed threshold alone finds others.
// A well-exposed frame is left exactly as it is.
TEST(FeatureExtractor, DimImageIsStretchedWellExposedOneUntouched) {
  const RgbdFrame bright = tum_frame();
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 2.0);  // sensor noise does not dim with the light
  const RgbdFrame dim = with_grey_levels(bright, [&](double v) { return v * 0.2 + noise(rng); });
  FeatureExtractorOptions off;
  off.dim_max_gain = 1.0;
  const FeatureExtractor plain(tum_camera(), off);
  const FeatureExtractor stretching(tum_camera());
  const FrameFeatures reference = plain.extract(bright);
  const FrameFeatures same = stretching.extract(bright);
  ASSERT_EQ(same.size(), reference.size());
  for (std::size_t i = 0; i < same.size(); ++i) {
    EXPECT_EQ(same.keypoints[i].px, reference.keypoints[i].px) << "feature " << i;
  }
  const double with = keypoint_overlap(stretching.extract(dim), reference);
  const double without = keypoint_overlap(plain.extract(dim), reference);
  std::cerr << "dim frame: " << with << " of the bright frame's corners with the stretch, "
            << without << " without\n";
  EXPECT_GE(with, 0.8);
  EXPECT_GT(with, without);
}

// FAST runs at threshold 20 first (a textured frame has its 3000 candidates there, at half the
// cost of 8); an image that leaves it short, low in contrast, is detected again at 8 and gets
// exactly the features the lower threshold gives.
TEST(FeatureExtractor, LowContrastFrameFallsBackToTheLowerFastThreshold) {
  const RgbdFrame flat = with_grey_levels(tum_frame(), [](double v) { return v * 0.3 + 90.0; });
  FeatureExtractorOptions two_pass, low_only, high_only;
  two_pass.dim_max_gain = low_only.dim_max_gain = high_only.dim_max_gain = 1.0;
  low_only.fast_threshold = 8;
  low_only.fast_threshold_fallback = 0;
  high_only.fast_threshold_fallback = 0;
  const FrameFeatures a = FeatureExtractor(tum_camera(), two_pass).extract(flat);
  const FrameFeatures low = FeatureExtractor(tum_camera(), low_only).extract(flat);
  const FrameFeatures high = FeatureExtractor(tum_camera(), high_only).extract(flat);
  std::cerr << "flat frame: " << a.size() << " features with the fallback, " << high.size()
            << " at threshold 20 alone\n";
  ASSERT_EQ(a.size(), low.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.keypoints[i].px, low.keypoints[i].px) << "feature " << i;
  }
  EXPECT_LT(keypoint_overlap(a, high), 0.9);
}

// The mechanism on its own: a dim wall whose texture differs by less than FAST's threshold has
// no corner for it; stretched, the same texture has plenty.
TEST(FeatureExtractor, DimLowContrastTextureGetsCornersOnlyWhenStretched) {
  PinholeCamera cam = tum_camera();
  Image wall = Image::allocate(640, 480, 1, PixelType::kU8);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.7);
  for (int y = 0; y < wall.height; ++y) {
    std::uint8_t* row = wall.row<std::uint8_t>(y);
    for (int x = 0; x < wall.width; ++x) {
      const bool dark = ((x / 24) + (y / 24)) % 2 == 0;
      row[x] = static_cast<std::uint8_t>(std::lround((dark ? 27.0 : 33.0) + noise(rng)));
    }
  }
  FeatureExtractorOptions off;
  off.dim_max_gain = 1.0;
  const std::size_t plain = FeatureExtractor(cam, off).extract(wall).size();
  const std::size_t stretched = FeatureExtractor(cam).extract(wall).size();
  std::cerr << "dim checkerboard: " << stretched << " features stretched, " << plain
            << " without\n";
  EXPECT_GE(stretched, 200u);
  EXPECT_LT(plain * 4, stretched);
}

TEST(FeatureExtractor, DepthBackProjectionMatchesDepthImage) {
  const PinholeCamera cam = tum_camera();
  const FeatureExtractor ex(cam);
  const RgbdFrame frame = tum_frame();
  const FrameFeatures f = ex.extract(frame);
  int with_depth = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (!f.has_depth(i)) continue;
    ++with_depth;
    const auto& k = f.keypoints[i];
    const int u = static_cast<int>(std::lround(k.px.x()));
    const int v = static_cast<int>(std::lround(k.px.y()));
    const double z = frame.depth.row<std::uint16_t>(v)[u] / 5000.0;
    EXPECT_NEAR(f.points_c[i].z(), z, 1e-12);
    const auto uv = cam.project(f.points_c[i]);
    ASSERT_TRUE(uv.has_value());
    EXPECT_NEAR((*uv - k.px).norm(), 0.0, 1e-9);
    EXPECT_GE(f.depth[i], ex.options().min_depth);
    EXPECT_LE(f.depth[i], ex.options().max_depth);
  }
  EXPECT_GT(with_depth, static_cast<int>(f.size()) / 2);
}

TEST(FeatureExtractor, MaxDepthRejectsFarPoints) {
  FeatureExtractorOptions o;
  o.max_depth = 1.5;
  const FeatureExtractor ex(tum_camera(), o);
  const FrameFeatures f = ex.extract(tum_frame());
  int with_depth = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.has_depth(i)) {
      ++with_depth;
      EXPECT_LE(f.points_c[i].z(), 1.5);
    }
  }
  const FrameFeatures all = FeatureExtractor(tum_camera()).extract(tum_frame());
  int all_depth = 0;
  for (std::size_t i = 0; i < all.size(); ++i) all_depth += all.has_depth(i) ? 1 : 0;
  EXPECT_LT(with_depth, all_depth);
}

// A keypoint without depth next to the sensor's readings sits on an object's outline (a depth
// step or the holes a sensor leaves there), which triangulation must not take for a point; one
// with no reading anywhere around it sees beyond the sensor's range.
TEST(FeatureExtractor, MarksFeaturesOnDepthOutlines) {
  FeatureExtractorOptions o;
  o.max_depth = 3.0;  // the TUM frame's far wall becomes "beyond range"
  const FeatureExtractor ex(tum_camera(), o);
  const RgbdFrame frame = tum_frame();
  const FrameFeatures f = ex.extract(frame);
  ASSERT_EQ(f.on_depth_step.size(), f.size());
  auto reading_within = [&](const Vec2& px, int r) {
    const int u = static_cast<int>(std::lround(px.x())), v = static_cast<int>(std::lround(px.y()));
    for (int y = std::max(0, v - r); y <= std::min(frame.depth.height - 1, v + r); ++y) {
      for (int x = std::max(0, u - r); x <= std::min(frame.depth.width - 1, u + r); ++x) {
        const double z = frame.depth.row<std::uint16_t>(y)[x] / frame.depth_scale;
        if (z >= o.min_depth && z <= o.max_depth) return true;
      }
    }
    return false;
  };
  int outline = 0, beyond = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.has_depth(i)) {
      EXPECT_EQ(f.on_depth_step[i], 0) << i;
    } else if (f.on_depth_step[i]) {
      ++outline;
      EXPECT_TRUE(reading_within(f.keypoints[i].px, 3)) << i;
    } else {
      ++beyond;
      EXPECT_FALSE(reading_within(f.keypoints[i].px, 0)) << i;
    }
  }
  EXPECT_GT(outline, 20);
  EXPECT_GT(beyond, 20);
  // Without a depth image nothing is known: the vector stays empty.
  EXPECT_TRUE(ex.extract(frame.color).on_depth_step.empty());
}

TEST(FeatureExtractor, IgnoreMaskKeepsFeaturesOut) {
  const FeatureExtractor ex(tum_camera());
  const RgbdFrame frame = tum_frame();
  Image ignore = Image::allocate(frame.color.width, frame.color.height, 1, PixelType::kU8);
  for (int y = 0; y < ignore.height; ++y) {
    for (int x = 0; x < ignore.width / 2; ++x) ignore.row<std::uint8_t>(y)[x] = 255;
  }
  const FrameFeatures f = ex.extract(frame, &ignore);
  ASSERT_GT(f.size(), 300u);
  for (const auto& k : f.keypoints) EXPECT_GE(k.px.x(), ignore.width / 2 - 1.0);
}

// A crowd filling part of the view must not take the scenery's features: with the movers'
// region set apart, the features there are those the whole image's bucketing gives it, and
// the rest of the image gets the whole target of its own.
TEST(FeatureExtractor, MoversRegionKeepsItsShareAndTheSceneryGetsTheWholeTarget) {
  const FeatureExtractor ex(tum_camera());
  const RgbdFrame frame = tum_frame();
  Image movers = Image::allocate(frame.color.width, frame.color.height, 1, PixelType::kU8);
  const int split = frame.color.width / 2;
  for (int y = 0; y < movers.height; ++y) {
    for (int x = 0; x < movers.width; ++x) movers.row<std::uint8_t>(y)[x] = x < split ? 255 : 0;
  }
  const FrameFeatures one = ex.extract(frame);
  const FrameFeatures apart = ex.extract(frame, nullptr, &movers);
  const auto split_by_region = [&](const FrameFeatures& f) {
    std::pair<std::set<std::pair<double, double>>, std::set<std::pair<double, double>>> out;
    for (const auto& k : f.keypoints) {
      // ORB's own position decides the region, and it is up to 1.5 px from ours: the 2 px
      // either side of the split are left out.
      if (k.px.x() < split - 2.0) out.first.insert({k.px.x(), k.px.y()});
      if (k.px.x() >= split + 2.0) out.second.insert({k.px.x(), k.px.y()});
    }
    return out;
  };
  const auto [one_in, one_out] = split_by_region(one);
  const auto [apart_in, apart_out] = split_by_region(apart);
  ASSERT_GT(one_in.size(), 200u);
  EXPECT_EQ(apart_in, one_in);
  EXPECT_TRUE(std::includes(apart_out.begin(), apart_out.end(), one_out.begin(), one_out.end()));
  std::cout << "features right of the split: " << one_out.size() << " with one budget, "
            << apart_out.size() << " with the movers apart; left: " << one_in.size() << "\n";
  EXPECT_GE(apart_out.size(), one_out.size() + 200);
  EXPECT_GT(apart.size(), 1000u);
  EXPECT_EQ(apart.depth.size(), apart.size());
}

TEST(FeatureExtractor, RetainDropsByIndexAndKeepsArraysAligned) {
  const FeatureExtractor ex(tum_camera());
  FrameFeatures f = ex.extract(tum_frame());
  const FrameFeatures orig = f;
  std::vector<std::uint8_t> keep(f.size());
  for (std::size_t i = 0; i < keep.size(); ++i) keep[i] = (i % 3 != 0);
  f.retain(keep);
  std::size_t j = 0;
  for (std::size_t i = 0; i < orig.size(); ++i) {
    if (!keep[i]) continue;
    ASSERT_LT(j, f.size());
    EXPECT_EQ(f.keypoints[j].px, orig.keypoints[i].px);
    EXPECT_EQ(f.descriptors[j], orig.descriptors[i]);
    EXPECT_EQ(f.depth[j], orig.depth[i]);
    EXPECT_EQ(f.sensor_depth[j], orig.sensor_depth[i]);
    EXPECT_EQ(f.on_depth_step[j], orig.on_depth_step[i]);
    ++j;
  }
  EXPECT_EQ(j, f.size());
  EXPECT_EQ(f.sensor_depth.size(), f.size());
  EXPECT_THROW(f.retain(std::vector<std::uint8_t>(3, 1)), std::invalid_argument);
}

TEST(FeatureExtractor, RadiusSearchEqualsBruteForce) {
  const FrameFeatures f = FeatureExtractor(tum_camera()).extract(tum_frame());
  for (const Vec2& c : {Vec2(100, 100), Vec2(320, 240), Vec2(630, 470), Vec2(-5, 10)}) {
    for (double r : {3.0, 15.0, 40.0}) {
      std::vector<int> got = f.in_radius(c.x(), c.y(), r, 1, 4);
      std::sort(got.begin(), got.end());
      std::vector<int> want;
      for (std::size_t i = 0; i < f.size(); ++i) {
        const auto& k = f.keypoints[i];
        if ((k.un - c).norm() <= r && k.level >= 1 && k.level <= 4)
          want.push_back(static_cast<int>(i));
      }
      EXPECT_EQ(got, want);
    }
  }
}

TEST(FeatureExtractor, UndistortsKeypointsWithTheCameraModel) {
  PinholeCamera cam = tum_camera();
  cam.model = DistortionModel::kRadTan;
  cam.dist = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};  // TUM fr1's published coefficients
  const FrameFeatures f = FeatureExtractor(cam).extract(tum_frame());
  double max_shift = 0.0;
  for (const auto& k : f.keypoints) {
    const Vec2 xn((k.un.x() - cam.cx) / cam.fx, (k.un.y() - cam.cy) / cam.fy);
    const Vec2 xd = cam.distort(xn);
    EXPECT_NEAR(cam.fx * xd.x() + cam.cx, k.px.x(), 1e-6);
    EXPECT_NEAR(cam.fy * xd.y() + cam.cy, k.px.y(), 1e-6);
    max_shift = std::max(max_shift, (k.un - k.px).norm());
  }
  EXPECT_GT(max_shift, 1.0);  // the distortion is real, so undistortion must move points
}

TEST(FeatureExtractor, RejectsBadInputs) {
  const FeatureExtractor ex(tum_camera());
  const RgbdFrame frame = tum_frame();
  const Image small = Image::allocate(10, 10, 1, PixelType::kU8);
  EXPECT_THROW(ex.extract(frame.color, &small), std::invalid_argument);
  EXPECT_THROW(ex.extract(frame.color, nullptr, &frame.color), std::invalid_argument);
  EXPECT_THROW(ex.extract(frame.depth), std::invalid_argument);
  EXPECT_THROW(ex.extract(frame, nullptr, &small), std::invalid_argument);
  EXPECT_THROW(ex.extract(frame, nullptr, &frame.depth), std::invalid_argument);
  FeatureExtractorOptions bad;
  bad.scale_factor = 1.0f;
  EXPECT_THROW(FeatureExtractor(tum_camera(), bad), std::invalid_argument);
}

}  // namespace
}  // namespace kestrel::tracking
