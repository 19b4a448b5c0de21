#include "tracking/corner_tracks.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

#include "core/so3.hpp"
#include "synthetic_scene.hpp"

namespace kestrel::tracking {
namespace {

constexpr double kScale = 5000.0;
constexpr double kWallX = 3.0;  // the wall is the plane world x = 3, facing the camera

struct Blob {
  double y, z, radius, amplitude;
};

// A bare wall's faint round blotches (corridor-dark's end wall): a few grey levels of contrast,
// a few centimetres across, nothing ORB's FAST ring would find twice.
std::vector<Blob> blotches(unsigned seed, double scale = 1.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> y(-3.0, 3.0), z(-1.0, 3.5), r(0.03 * scale, 0.08 * scale),
      a(-10, 10);
  std::vector<Blob> b(static_cast<std::size_t>(500 / scale));
  for (auto& x : b) x = {y(rng), z(rng), r(rng), a(rng)};
  return b;
}

struct View {
  Image gray, depth;
};

// The wall seen from T_w_c: grey from the blotches plus sensor noise, depth along the ray.
View render(const std::vector<Blob>& blobs, const SE3& T_w_c, const PinholeCamera& cam,
            double grey_noise, unsigned seed) {
  View v{Image::allocate(cam.width, cam.height, 1, PixelType::kU8),
         Image::allocate(cam.width, cam.height, 1, PixelType::kU16)};
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, grey_noise);
  for (int y = 0; y < cam.height; ++y) {
    auto* g = v.gray.row<std::uint8_t>(y);
    auto* d = v.depth.row<std::uint16_t>(y);
    for (int x = 0; x < cam.width; ++x) {
      const Vec3 dir = T_w_c.so3() * Vec3((x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, 1.0);
      const double s = (kWallX - T_w_c.translation().x()) / dir.x();
      const Vec3 p = T_w_c.translation() + s * dir;
      double grey = 60.0;
      for (const Blob& b : blobs) {
        const double r2 = (p.y() - b.y) * (p.y() - b.y) + (p.z() - b.z) * (p.z() - b.z);
        if (r2 < 9.0 * b.radius * b.radius) {
          grey += b.amplitude * std::exp(-r2 / (2.0 * b.radius * b.radius));
        }
      }
      g[x] = static_cast<std::uint8_t>(std::clamp(std::lround(grey + noise(rng)), 0L, 255L));
      const double depth = s * (T_w_c.so3().inverse() * dir).z();
      d[x] = static_cast<std::uint16_t>(std::lround(depth * kScale));
    }
  }
  return v;
}

struct Step {
  SE3 T_w_ref, T_w_cur;
  View ref, cur;
};

Step wall_step(double grey_noise, double distance_m = kWallX) {
  const PinholeCamera cam;
  // The blotches as many pixels across at any distance (ORB-free either way).
  const auto blobs = blotches(7, distance_m / kWallX);
  const double x = kWallX - distance_m;
  Step s;
  s.T_w_ref = test::camera_facing_x(Vec3(x, 0, 1.2), 0.0);
  s.T_w_cur = test::camera_facing_x(Vec3(x + 0.012, -0.015, 1.206), 0.006);
  s.ref = render(blobs, s.T_w_ref, cam, grey_noise, 1);
  s.cur = render(blobs, s.T_w_cur, cam, grey_noise, 2);
  return s;
}

// The IMU's prediction, off along the wall (where depth alone cannot correct it) and in yaw.
DepthAlignmentPrior off_prior(const Step& s) {
  const SE3 wrong(SO3::exp(Vec3(0, 0, 0.002)) * s.T_w_cur.so3(),
                  s.T_w_cur.translation() + Vec3(0.0, 0.012, -0.01));
  DepthAlignmentPrior p;
  p.T_ref_cur = s.T_w_ref.inverse() * wrong;
  p.rotation_sigma = 0.005;
  p.translation_sigma = 0.02;
  return p;
}

double translation_error(const Step& s, const SE3& T_ref_cur) {
  return ((s.T_w_ref * T_ref_cur).translation() - s.T_w_cur.translation()).norm();
}

TEST(CornerTracks, FixWhatDepthLeavesAlongABareBlotchedWall) {
  const PinholeCamera cam;
  const Step s = wall_step(1.5);
  const DepthAlignmentPrior prior = off_prior(s);
  ASSERT_GT(translation_error(s, prior.T_ref_cur), 0.015);

  const DepthAlignmentResult depth_only =
      align_depth(s.ref.depth, kScale, s.cur.depth, kScale, cam, prior);
  ASSERT_TRUE(depth_only.ok);
  EXPECT_GT(translation_error(s, depth_only.T_ref_cur), 0.01);  // the slide along the wall stays
  EXPECT_LT(depth_only.weakest_information, DepthAlignmentOptions{}.min_information);

  const CornerTracks c = follow_corners(s.ref.gray, s.ref.depth, kScale, s.cur.gray, cam);
  EXPECT_GE(c.tracks.size(), 60u) << c.corners << " corners";
  const DepthAlignmentResult r =
      align_depth(s.ref.depth, kScale, s.cur.depth, kScale, cam, prior, {}, {}, c.tracks);
  ASSERT_TRUE(r.ok);
  EXPECT_GE(r.track_inliers, static_cast<int>(c.tracks.size() * 9 / 10));
  EXPECT_GT(r.weakest_information, DepthAlignmentOptions{}.min_information);
  EXPECT_LT(translation_error(s, r.T_ref_cur), 0.003);
  const SE3 T_w_est = s.T_w_ref * r.T_ref_cur;
  EXPECT_LT((T_w_est.so3() * s.T_w_cur.so3().inverse()).log().norm(), 3e-4);
}

// A third of the tracks slid 6-10 px (a mover, a corner LK lost): the rest still decide.
TEST(CornerTracks, WrongTracksDoNotPullTheStep) {
  const PinholeCamera cam;
  const Step s = wall_step(1.5);
  CornerTracks c = follow_corners(s.ref.gray, s.ref.depth, kScale, s.cur.gray, cam);
  ASSERT_GE(c.tracks.size(), 60u);
  for (std::size_t i = 0; i < c.tracks.size(); i += 3) {
    c.tracks[i].uv_cur += Vec2(6.0 + static_cast<double>(i % 5), -3.0);
  }
  const DepthAlignmentResult r =
      align_depth(s.ref.depth, kScale, s.cur.depth, kScale, cam, off_prior(s), {}, {}, c.tracks);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(translation_error(s, r.T_ref_cur), 0.004);
  EXPECT_LE(r.track_inliers, static_cast<int>(c.tracks.size() * 2 / 3) + 1);
}

// At a wall 1.1 m away the prior's 1.6 cm is 7 px, beyond the tracks' 4 px gate, and the worst
// case of wrong tracks, a third of them slid to just where the prior expects them, lie inside
// it (corridor-dark, seed 6, 18.7 s: the step came out 16 mm off). The tracks' consensus
// decides where the alignment starts.
TEST(CornerTracks, ACloseWallAndAFarPriorStillGiveTheStep) {
  const PinholeCamera cam;
  const Step s = wall_step(1.5, 1.1);
  const DepthAlignmentPrior prior = off_prior(s);
  CornerTracks c = follow_corners(s.ref.gray, s.ref.depth, kScale, s.cur.gray, cam);
  ASSERT_GE(c.tracks.size(), 40u) << c.corners << " corners";
  for (std::size_t i = 0; i < c.tracks.size(); i += 3) {
    const auto at_prior = cam.project(prior.T_ref_cur.inverse() * c.tracks[i].p_ref);
    ASSERT_TRUE(at_prior);
    c.tracks[i].uv_cur = *at_prior + Vec2(0.5, -0.5);
  }
  const DepthAlignmentResult r =
      align_depth(s.ref.depth, kScale, s.cur.depth, kScale, cam, prior, {}, {}, c.tracks);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(translation_error(s, r.T_ref_cur), 0.002);
  EXPECT_GE(r.track_inliers, static_cast<int>(c.tracks.size() / 2));
}

// A movers' box covering the view leaves nothing to follow.
TEST(CornerTracks, LeaveTheMoversBoxesOut) {
  const PinholeCamera cam;
  const Step s = wall_step(1.5);
  const std::vector<PixelBox> all = {{0, 0, double(cam.width), double(cam.height)}};
  const CornerTracks c = follow_corners(s.ref.gray, s.ref.depth, kScale, s.cur.gray, cam, {}, all);
  EXPECT_EQ(c.corners, 0);
  EXPECT_TRUE(c.tracks.empty());
}

// A wall with no texture but noise: the corners the noise makes do not come back from the next
// frame, and no track is invented.
TEST(CornerTracks, NoiseAloneGivesNoTracks) {
  const PinholeCamera cam;
  const std::vector<Blob> bare;
  Step s;
  s.T_w_ref = test::camera_facing_x(Vec3(0, 0, 1.2), 0.0);
  s.T_w_cur = test::camera_facing_x(Vec3(0.012, -0.015, 1.206), 0.006);
  s.ref = render(bare, s.T_w_ref, cam, 1.5, 1);
  s.cur = render(bare, s.T_w_cur, cam, 1.5, 2);
  const CornerTracks c = follow_corners(s.ref.gray, s.ref.depth, kScale, s.cur.gray, cam);
  EXPECT_GT(c.corners, 100);
  EXPECT_LT(c.tracks.size(), 5u);
}

TEST(CornerTracks, RejectImagesOfTheWrongKind) {
  const PinholeCamera cam;
  const Step s = wall_step(0.0);
  EXPECT_THROW(follow_corners(s.ref.gray, s.ref.gray, kScale, s.cur.gray, cam),
               std::invalid_argument);
  EXPECT_THROW(follow_corners(s.ref.depth, s.ref.depth, kScale, s.cur.gray, cam),
               std::invalid_argument);
  EXPECT_THROW(follow_corners(s.ref.gray, s.ref.depth, 0.0, s.cur.gray, cam),
               std::invalid_argument);
}

}  // namespace
}  // namespace kestrel::tracking
