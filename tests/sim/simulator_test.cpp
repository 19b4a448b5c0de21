// The simulator's truth must be consistent with its pictures: depth and poses agree, masks are
// exactly the movers, boxes bound their masks, and the same seed gives the same bytes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "sim/simulator.hpp"

namespace kestrel::sim {
namespace {

const char* kSmallWorld = R"(
name: small
seed: 3
duration: 1.5
sensor: {noise: false, edge_holes: 0.0}
world:
  ground: {size: [12, 12], texture: {style: tiles}}
  rooms:
    - {center: [0, 0, 1.5], size: [10, 10, 3], texture: {style: posters, scale: 3}}
  objects:
    - {label: dining table, center: [2.5, 0.5, 0.375], size: [1.2, 0.8, 0.75]}
    - {label: chair, center: [2.5, -0.4, 0.475], size: [0.5, 0.5, 0.95], yaw_deg: 90}
movers:
  - {type: person, sprite: 0, path: [[3.0, -2.0], [3.0, 2.0]], speed: 1.2, mode: pingpong}
  - {type: person, sprite: 1, path: [[2.0, 2.0], [2.2, -2.0]], speed: 1.0, mode: pingpong}
  - {type: box, label: box, path: [[4, -1], [4, 1]], speed: 0.5, size: [0.5, 0.5, 0.5]}
  - {type: spin, center: [1.8, 1.4, 0], rate_deg: 90}
  - {type: chair, path: [[2.8, -1.2], [2.8, -0.2]], start: 0.5, speed: 0.4, mode: once}
  - {type: person, sprite: 4, path: [[3.5, 1.5], [3.5, -1.5]], speed: 0.8, mode: pingpong}
  - {type: vehicle, photo: car-red-wagon, path: [[4.0, 2.5], [4.0, -2.5]], speed: 2.0, mode: pingpong, size: [4.0, 1.8, 1.5]}
  - {type: bird, path: [[2.0, -1.5, 1.6], [2.5, 1.5, 1.9]], speed: 2.0, mode: pingpong, size: [0.35, 0.8, 0.12]}
trajectory:
  kind: handheld
  segment_time: 0.8
  waypoints: [[-1, 0, 1.4, 0], [-0.6, 0.3, 1.45, 10], [-0.3, 0.1, 1.4, -5]]
)";

Scenario small(bool noise = false, bool no_movers = false) {
  ScenarioOverrides ov;
  ov.no_movers = no_movers;
  Scenario s = parse_scenario(kSmallWorld, "small", ov);
  s.sensor.noise = noise;
  if (noise) s.sensor.edge_holes = 0.5;
  return s;
}

double depth_at(const Image& d, int x, int y, double scale) {
  return d.row<std::uint16_t>(y)[x] / scale;
}

TEST(Simulator, StaticPixelsReprojectBetweenFramesWithinOnePixel) {
  Simulator sim(small());
  const PinholeCamera& cam = sim.calibration().camera;
  const double scale = sim.calibration().depth_scale;
  for (int k : {3, 20}) {
    const SimFrame a = sim.render(k);
    const SimFrame b = sim.render(k + 5);
    const SE3 T_w_a = sim.camera_pose(a.time), T_w_b = sim.camera_pose(b.time);
    const SE3 T_b_a = T_w_b.inverse() * T_w_a, T_a_b = T_b_a.inverse();
    std::vector<double> err;
    for (int y = 2; y < cam.height - 2; y += 6) {
      for (int x = 2; x < cam.width - 2; x += 6) {
        if (a.mask.row<std::uint16_t>(y)[x] != 0) continue;
        const double za = depth_at(a.depth, x, y, scale);
        if (za <= 0) continue;
        const Vec3 pb = T_b_a * (za * cam.unproject(Vec2(x, y)));
        const auto uv = cam.project(pb);
        if (!uv || !cam.in_image(*uv, 1)) continue;
        const int xb = static_cast<int>(std::lround(uv->x())),
                  yb = static_cast<int>(std::lround(uv->y()));
        if (b.mask.row<std::uint16_t>(yb)[xb] != 0) continue;
        const double zb = depth_at(b.depth, xb, yb, scale);
        if (zb <= 0 || std::fabs(zb - pb.z()) > 0.02 * pb.z()) continue;  // occluded or an edge
        // Back from frame b's depth into frame a: the round trip must land where it started.
        const auto back = cam.project(T_a_b * (zb * cam.unproject(Vec2(xb, yb))));
        ASSERT_TRUE(back.has_value());
        err.push_back((*back - Vec2(x, y)).norm());
      }
    }
    ASSERT_GT(err.size(), 2000u);
    std::nth_element(err.begin(), err.begin() + err.size() / 2, err.end());
    EXPECT_LT(err[err.size() / 2], 1.0) << "frame " << k;
  }
}

TEST(Simulator, MasksCoverExactlyTheMoversAndBoxesBoundThem) {
  Simulator with(small());
  Simulator without(small(false, true));
  int frames_with_movers = 0;
  for (int k = 0; k < with.frame_count(); k += 4) {
    const SimFrame a = with.render(k);
    const SimFrame b = without.render(k);
    const int W = a.color.width, H = a.color.height;
    std::size_t mover_pixels = 0, changed = 0;
    for (int y = 0; y < H; ++y) {
      const auto* ma = a.mask.row<std::uint16_t>(y);
      const auto* da = a.depth.row<std::uint16_t>(y);
      const auto* db = b.depth.row<std::uint16_t>(y);
      const auto* ca = a.color.row<std::uint8_t>(y);
      const auto* cb = b.color.row<std::uint8_t>(y);
      for (int x = 0; x < W; ++x) {
        const bool same = da[x] == db[x] && std::memcmp(ca + 3 * x, cb + 3 * x, 3) == 0;
        if (ma[x] == 0) {
          ASSERT_TRUE(same) << "static pixel changed by a mover at " << x << "," << y << " frame "
                            << k;
        } else {
          ++mover_pixels;
          changed += !same;
          ASSERT_TRUE(db[x] == 0 || da[x] <= db[x])
              << "mover behind the scene at " << x << "," << y;
        }
      }
    }
    // Where a mover is, the picture is the mover's (a few texels may match the scene by chance).
    EXPECT_GE(changed, mover_pixels * 95 / 100);
    frames_with_movers += mover_pixels > 0;

    for (const SimBox& box : a.boxes) {
      if (box.instance > static_cast<int>(with.world().movers().size())) continue;
      int x0 = W, y0 = H, x1 = -1, y1 = -1, n = 0;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          if (a.mask.row<std::uint16_t>(y)[x] == box.instance) {
            x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y),
            ++n;
          }
      EXPECT_EQ(box.x_min, x0);
      EXPECT_EQ(box.y_min, y0);
      EXPECT_EQ(box.x_max, x1 + 1);
      EXPECT_EQ(box.y_max, y1 + 1);
      EXPECT_EQ(box.pixels, n);
      EXPECT_GE(box.occluded, 0.0);
      EXPECT_LE(box.occluded, 1.0);
    }
  }
  EXPECT_GT(frames_with_movers, 5);
}

TEST(Simulator, MovingFlagsFollowTheSchedule) {
  Simulator sim(small());
  // Mover 5 (the pushed chair) starts at 0.5 s.
  const auto moving_of = [&](int k, int id) {
    for (const SimBox& b : sim.render(k).boxes)
      if (b.instance == id) return static_cast<int>(b.moving);
    return -1;
  };
  EXPECT_EQ(moving_of(3, 5), 0);
  EXPECT_EQ(moving_of(30, 5), 1);
}

// The bird (mover 8) flies above the floor, is flagged moving, and beats its wings: its box
// changes height from frame to frame even where its path is level.
TEST(Simulator, BirdFliesFlapsAndIsInMasksAndBoxes) {
  Simulator sim(small());
  const int bird = 8;
  ASSERT_EQ(sim.world().movers()[bird - 1].type, "bird");
  std::vector<int> heights;
  for (int k = 0; k < sim.frame_count(); k += 2) {
    const SimFrame f = sim.render(k);
    for (const SimBox& b : f.boxes) {
      if (b.instance != bird) continue;
      EXPECT_EQ(b.label, "bird");
      EXPECT_TRUE(b.moving);
      EXPECT_GT(b.pixels, 0);
      heights.push_back(b.y_max - b.y_min);
      // Its pixels carry its id in the mask, and the mask holds exactly its box's count.
      int n = 0;
      for (int y = b.y_min; y < b.y_max; ++y)
        for (int x = b.x_min; x < b.x_max; ++x) n += f.mask.row<std::uint16_t>(y)[x] == bird;
      EXPECT_EQ(n, b.pixels);
    }
  }
  ASSERT_GT(heights.size(), 10u) << "the bird should be in view most of the run";
  const auto [lo, hi] = std::minmax_element(heights.begin(), heights.end());
  EXPECT_GT(*hi - *lo, 5) << "wings do not beat";
}

TEST(Simulator, MotionBlurSmearsColourButKeepsTheTruth) {
  Scenario blurred = small();
  blurred.sensor.motion_blur = 4;
  blurred.sensor.exposure_time = 0.03;
  Simulator sharp(small()), blur(blurred);
  const SimFrame a = sharp.render(12), b = blur.render(12);
  EXPECT_EQ(*a.depth.data, *b.depth.data);
  EXPECT_EQ(*a.mask.data, *b.mask.data);
  EXPECT_NE(*a.color.data, *b.color.data);
  // Blur averages neighbours: the image's high-frequency energy drops.
  const auto energy = [](const Image& im) {
    double e = 0;
    for (int y = 0; y < im.height; ++y)
      for (int x = 1; x < im.width; ++x) {
        const double d = im.row<std::uint8_t>(y)[3 * x] - im.row<std::uint8_t>(y)[3 * x - 3];
        e += d * d;
      }
    return e;
  };
  EXPECT_LT(energy(b.color), energy(a.color));
}

std::uint64_t fnv(const std::uint8_t* p, std::size_t n, std::uint64_t h) {
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ULL;
  return h;
}

std::uint64_t run_hash(Scenario s) {
  Simulator sim(std::move(s));
  std::uint64_t h = 1469598103934665603ULL;
  for (int k = 0; k < sim.frame_count(); k += 3) {
    const SimFrame f = sim.render(k);
    h = fnv(f.color.data->data(), f.color.data->size(), h);
    h = fnv(f.depth.data->data(), f.depth.data->size(), h);
    h = fnv(f.mask.data->data(), f.mask.data->size(), h);
    h = fnv(reinterpret_cast<const std::uint8_t*>(&f.stamp), sizeof f.stamp, h);
  }
  for (const ImuSample& s : sim.imu()) {
    h = fnv(reinterpret_cast<const std::uint8_t*>(s.gyro.data()), 3 * sizeof(double), h);
    h = fnv(reinterpret_cast<const std::uint8_t*>(s.acc.data()), 3 * sizeof(double), h);
  }
  return h;
}

TEST(Simulator, SameSeedSameBytesOtherSeedOtherBytes) {
  Scenario a = small(true);
  a.sensor.jitter = 0.002;
  a.sensor.drop_rate = 0.1;
  const std::uint64_t h1 = run_hash(a);
  const std::uint64_t h2 = run_hash(a);
  EXPECT_EQ(h1, h2);
  a.seed = 4;
  EXPECT_NE(run_hash(a), h1);
}

// A shuffled ground is the same geometry with its texture repeats turned and shaded: depth and
// masks do not change, the colour of the ground does, and two repeats that were identical are
// not any more.
TEST(Simulator, ShuffledGroundChangesOnlyTheGroundsLook) {
  Scenario plain = small(false, true);
  Scenario shuffled = plain;
  shuffled.ground_shuffle = true;
  Simulator a(plain), b(shuffled);
  const SimFrame fa = a.render(10), fb = b.render(10);
  ASSERT_EQ(fa.depth.data->size(), fb.depth.data->size());
  // The ground is cut into more triangles, so interpolated depth may differ by rounding, and a
  // pixel on a new seam may fall to either side; nothing else moves.
  std::size_t depth_moved = 0;
  for (int y = 0; y < fa.depth.height; ++y) {
    for (int x = 0; x < fa.depth.width; ++x) {
      const int da = fa.depth.row<std::uint16_t>(y)[x], db = fb.depth.row<std::uint16_t>(y)[x];
      depth_moved += std::abs(da - db) > 2 ? 1 : 0;
    }
  }
  EXPECT_LT(depth_moved, static_cast<std::size_t>(fa.depth.width * fa.depth.height) / 1000);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < fa.color.data->size(); ++i) {
    differ += (*fa.color.data)[i] != (*fb.color.data)[i] ? 1 : 0;
  }
  EXPECT_GT(differ, fa.color.data->size() / 20);  // the ground fills a good part of the view
  // Same seed, same shuffle.
  Simulator c(shuffled);
  EXPECT_EQ(*c.render(10).color.data, *fb.color.data);
}

TEST(Simulator, NoisyDepthHasHolesAtEdgesAndGrowingError) {
  Simulator exact(small(false));
  Simulator noisy(small(true));
  const SimFrame a = exact.render(10), b = noisy.render(10);
  std::size_t holes = 0, both = 0;
  double err2 = 0.0;
  for (int y = 0; y < a.depth.height; ++y)
    for (int x = 0; x < a.depth.width; ++x) {
      const int da = a.depth.row<std::uint16_t>(y)[x], db = b.depth.row<std::uint16_t>(y)[x];
      if (da > 0 && db == 0) ++holes;
      if (da > 0 && db > 0) {
        ++both;
        const double z = da / 5000.0, e = (db - da) / 5000.0;
        err2 += (e / (z * z)) * (e / (z * z));
      }
    }
  EXPECT_GT(holes, 100u);
  // Normalized by z^2 the error has the configured sigma.
  const double a_est = std::sqrt(err2 / static_cast<double>(both));
  EXPECT_NEAR(a_est, 0.003, 0.0006);
}

}  // namespace
}  // namespace kestrel::sim
