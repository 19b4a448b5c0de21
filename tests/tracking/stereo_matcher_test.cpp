#include "tracking/stereo_matcher.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <stdexcept>

#include "eval/trajectory_evaluation.hpp"
#include "io/dataset.hpp"
#include "io/trajectory_io.hpp"
#include "synthetic_scene.hpp"
#include "tests/test_paths.hpp"
#include "tracking/tracker.hpp"

namespace kestrel::tracking {
namespace {

std::string micro_dir() { return test::shared_data("euroc/V1_01_micro").string(); }

StereoFrame first_stereo_frame(io::MeasurementSource& src) {
  while (auto m = src.next()) {
    if (const auto* s = std::get_if<StereoFrame>(&*m)) return *s;
  }
  throw std::runtime_error("no stereo frame in " + micro_dir());
}

TEST(StereoMatcher, EurocDepthsAgreeWithTheRoomScale) {
  auto src = io::open_dataset("euroc:" + micro_dir());
  const Calibration& calib = src->calibration();
  ASSERT_TRUE(calib.is_stereo());
  const StereoFrame pair = first_stereo_frame(*src);
  FeatureExtractor extractor(calib.camera);
  StereoMatcher stereo(calib.stereo_rig(), extractor.options());
  EXPECT_NEAR(stereo.baseline(), 0.110, 0.002);  // EuRoC's rig: 11 cm

  FrameFeatures f = extractor.extract(pair.left);
  const auto t0 = std::chrono::steady_clock::now();
  const StereoStats st = stereo.compute_depth(f, pair.left, pair.right);
  std::cout
      << "stereo: " << st.matched << " of " << st.candidates << " features got a depth in "
      << std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count()
      << " ms\n";
  EXPECT_GT(st.matched, 300);
  // V1 is a room a few metres across: every depth lies inside it, most within 6 m.
  int far = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (!f.has_depth(i)) continue;
    EXPECT_GT(f.depth[i], 0.1);
    EXPECT_NEAR(f.points_c[i].z(), f.depth[i], 1e-12);
    // The point projects back onto its own keypoint (undistorted pixel), within a pixel.
    const Vec3& p = f.points_c[i];
    const Vec2 uv(calib.camera.fx * p.x() / p.z() + calib.camera.cx,
                  calib.camera.fy * p.y() / p.z() + calib.camera.cy);
    EXPECT_LT((uv - f.keypoints[i].un).norm(), 1.0) << "feature " << i;
    far += f.depth[i] > 6.0 ? 1 : 0;
  }
  EXPECT_LT(far, st.matched / 10);
}

// A rendered pair with exact depth: the right camera 12 cm to the right and turned by a
// degree, so rectification has work to do. Stereo depth must agree with the rendered depth.
TEST(StereoMatcher, RenderedPairDepthMatchesTheTruth) {
  PinholeCamera cam;
  cam.fx = cam.fy = 525.0;
  cam.cx = 319.5;
  cam.cy = 239.5;
  const SE3 T_left_right(SO3::exp(Vec3(0.0, 0.017, 0.005)), Vec3(0.12, 0.002, 0.0));
  const test::SyntheticScene scene = test::SyntheticScene::office();
  const SE3 T_w_left;
  const RgbdFrame left = scene.render(cam, T_w_left);
  const RgbdFrame right = scene.render(cam, T_w_left * T_left_right);
  FeatureExtractor extractor(cam);
  StereoMatcher stereo(StereoRig{cam, cam, T_left_right}, extractor.options());
  EXPECT_NEAR(stereo.baseline(), 0.12, 0.001);
  FrameFeatures f = extractor.extract(left.color);
  const StereoStats st = stereo.compute_depth(f, left.color, right.color);
  // Truth: the same features back-projected with the rendered depth.
  const FrameFeatures truth = extractor.extract(left);
  std::vector<double> rel, signed_rel;
  int gross = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (!f.has_depth(i) || !truth.has_depth(i)) continue;
    const double e = std::abs(f.depth[i] - truth.depth[i]) / truth.depth[i];
    signed_rel.push_back((f.depth[i] - truth.depth[i]) / truth.depth[i]);
    rel.push_back(e);
    gross += e > 0.1 ? 1 : 0;
  }
  ASSERT_GT(rel.size(), 300u) << st.matched << " of " << st.candidates;
  std::nth_element(rel.begin(), rel.begin() + static_cast<long>(rel.size() / 2), rel.end());
  std::nth_element(signed_rel.begin(),
                   signed_rel.begin() + static_cast<long>(signed_rel.size() / 2), signed_rel.end());
  std::cout << "rendered pair: " << st.matched << " depths, median relative error "
            << rel[rel.size() / 2] * 100.0 << " % (signed "
            << signed_rel[signed_rel.size() / 2] * 100.0 << " %), " << gross
            << " off by more than 10 %\n";
  // At 1.5-3 m a 12 cm baseline gives 21-42 px of disparity: sub-pixel matching (a few tenths
  // of a pixel, more on coarse pyramid levels) keeps depth within 2 %, and without bias.
  EXPECT_LT(rel[rel.size() / 2], 0.02);
  EXPECT_LT(std::abs(signed_rel[signed_rel.size() / 2]), 0.005);
  EXPECT_LT(gross, static_cast<int>(rel.size()) / 20);
}

TEST(StereoMatcher, RejectsImagesOfTheWrongSize) {
  auto src = io::open_dataset("euroc:" + micro_dir());
  const Calibration& calib = src->calibration();
  FeatureExtractor extractor(calib.camera);
  StereoMatcher stereo(calib.stereo_rig(), extractor.options());
  const StereoFrame pair = first_stereo_frame(*src);
  FrameFeatures f = extractor.extract(pair.left);
  const Image small = Image::allocate(320, 240, 1, PixelType::kU8);
  EXPECT_THROW(stereo.compute_depth(f, pair.left, small), std::invalid_argument);
}

// The whole micro clip (a still start: the vehicle does not move) through the RGB-D tracker
// with stereo depth: never lost, and APE within millimetres of the constant ground truth.
TEST(StereoMatcher, EurocMicroClipTrackedWithoutDrift) {
  auto src = io::open_dataset("euroc:" + micro_dir());
  const Calibration calib = src->calibration();
  Tracker tracker(calib.camera);
  StereoMatcher stereo(calib.stereo_rig(), tracker.extractor().options());
  Trajectory est;
  int frames = 0, lost = 0;
  while (auto m = src->next()) {
    const auto* s = std::get_if<StereoFrame>(&*m);
    if (!s) continue;
    ++frames;
    FrameFeatures f = tracker.extractor().extract(s->left, nullptr, nullptr, 5000.0, s->t);
    stereo.compute_depth(f, s->left, s->right);
    const TrackResult r = tracker.track(std::move(f));
    ASSERT_TRUE(r.T_w_c.is_finite());
    if (r.state == TrackingState::kLost || r.state == TrackingState::kInitializing) {
      ++lost;
      continue;
    }
    est.push_back(to_seconds(s->t), r.T_w_c * calib.T_body_camera.inverse());
  }
  EXPECT_EQ(frames, 95);
  EXPECT_EQ(lost, 0);
  const io::PoseSeries gt = io::read_pose_series(
      test::shared_data("euroc/V1_01_micro/groundtruth_open_vins/V1_01_easy.csv").string());
  eval::ApeOptions ape;
  ape.association.method = eval::AssociationMethod::kEvo;
  ape.association.max_diff = 0.01;
  ape.alignment = eval::Alignment::kSe3;
  const eval::Evaluation e = eval::evaluate_ape(gt, io::to_pose_series(est), ape);
  std::cout << "EuRoC V1_01_micro stereo: " << est.size() << " poses, APE rmse "
            << e.stats.rmse * 1000.0 << " mm over " << e.stats.count << " pairs, "
            << tracker.map().num_keyframes() << " keyframes, " << tracker.map().num_points()
            << " points\n";
  EXPECT_GT(e.stats.count, 90u);
  // The issue asks for 5 cm; a constant pose scores 0.81 mm here, so more than 5 mm is drift.
  EXPECT_LT(e.stats.rmse, 0.005);
}

}  // namespace
}  // namespace kestrel::tracking
