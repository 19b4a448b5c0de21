// The dynamic built-ins must be as hard as TUM's walking sequences: movers cover at least 25 %
// of the image in at least a third of the frames, and come close to the camera at times.
// Market: most walkers are partly hidden by others.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "sim/simulator.hpp"

namespace kestrel::sim {
namespace {

struct Coverage {
  double share_quarter = 0.0;  // frames with movers >= 25 % of the image
  double max_fraction = 0.0;
  double occluded_people = 0.0;  // person boxes more than 5 % hidden
};

Coverage measure(const std::string& name, int stride) {
  Simulator sim(load_scenario(name));
  int frames = 0, quarter = 0, people = 0, hidden = 0;
  double max_fraction = 0.0;
  for (int k = 0; k < sim.frame_count(); k += stride) {
    const SimFrame f = sim.render(k);
    ++frames;
    quarter += f.mover_fraction >= 0.25;
    max_fraction = std::max(max_fraction, f.mover_fraction);
    for (const SimBox& b : f.boxes) {
      if (b.label != "person") continue;
      ++people;
      hidden += b.occluded > 0.05;
    }
  }
  Coverage c{static_cast<double>(quarter) / frames, max_fraction,
             people ? static_cast<double>(hidden) / people : 0.0};
  std::printf("%s: movers >= 25%% in %.0f%% of frames, max %.0f%%, %.0f%% of people occluded\n",
              name.c_str(), 100 * c.share_quarter, 100 * c.max_fraction, 100 * c.occluded_people);
  return c;
}

TEST(ScenarioDifficulty, CafeMarketAndUavAreAsHardAsTumWalking) {
  for (const char* name : {"cafe", "market", "uav-zigzag"}) {
    const Coverage c = measure(name, 10);
    EXPECT_GE(c.share_quarter, 1.0 / 3.0) << name;
    EXPECT_GE(c.max_fraction, 0.4) << name << ": movers never come close";
    if (std::string(name) == "market") {
      EXPECT_GT(c.occluded_people, 0.5);
    }
  }
}

// Hard, but not impossible: on its pad the drone sees the plaza's traffic from metres away.
// With the pad at a lane's edge, cars passed 0.1 m from it and filled up to 97% of the view
// 1.2 m from the lens for 3.5 s of take-off and of landing: no camera tracks that.
TEST(ScenarioDifficulty, UavTakesOffAndLandsClearOfTraffic) {
  Simulator sim(load_scenario("uav-zigzag"));
  const double fps = sim.calibration().fps;
  const int last = sim.frame_count() - 1;
  const int on_pad = static_cast<int>(4.0 * fps);  // take-off: climbing to 2.5 m and beyond
  double worst = 0.0;
  int judged = 0;
  for (int k = 0; k <= last; k += 5) {
    if (k > on_pad && k < last - on_pad) continue;
    const SimFrame f = sim.render(k);
    worst = std::max(worst, f.mover_fraction);
    ++judged;
    EXPECT_LE(f.mover_fraction, 0.15) << "frame " << k;
  }
  std::printf("uav-zigzag on and near its pad: %d frames, movers cover at most %.0f%%\n", judged,
              100 * worst);
}

// Also hard, not impossible: on its pad and lifting off, the drone does not wobble. Its lens is
// 0.3 m from bare paving there, under the depth sensor's 0.4 m for most of the view; bobbing with
// the hovering wobble at up to 0.7 m/s, the few features with depth moved 18-26 px a frame and
// three draws in six could not track their first 1.5 s. The wobble is in full once airborne.
TEST(ScenarioDifficulty, UavLiftsOffItsPadWithoutWobbleAndWobblesAloft) {
  for (const std::uint64_t seed : {1u, 4u, 5u}) {
    Scenario sc = load_scenario("uav-zigzag");
    sc.seed = seed;
    const SplineTrajectory traj = make_trajectory(sc);
    Scenario calm = sc;
    calm.trajectory.wobble_position = calm.trajectory.wobble_rotation = 0.0;
    const SplineTrajectory smooth = make_trajectory(calm);
    const auto off_path = [&](double t) {
      const BodyState a = traj.state(t), b = smooth.state(t);
      return std::max({(a.T_w_b.translation() - b.T_w_b.translation()).norm(),
                       (a.v_w - b.v_w).norm(), (a.omega_b - b.omega_b).norm()});
    };
    // The first second: on the pad and lifting off (still under 0.4 m).
    double near_pad = 0.0;
    for (double t = 0.0; t <= 1.0; t += 0.01) near_pad = std::max(near_pad, off_path(t));
    EXPECT_LT(near_pad, 2e-3) << "seed " << seed;
    // Aloft (8 m, the zig-zag) the body departs from the smooth path by centimetres.
    double aloft = 0.0;
    for (double t = 10.0; t <= 14.0; t += 0.05) aloft = std::max(aloft, off_path(t));
    EXPECT_GT(aloft, 0.03) << "seed " << seed;
  }
}

TEST(ScenarioDifficulty, OfficeStaticHasNoMovers) {
  Simulator sim(load_scenario("office-static"));
  EXPECT_TRUE(sim.world().movers().empty());
  EXPECT_GE(sim.world().objects().size(), 5u);
}

}  // namespace
}  // namespace kestrel::sim
