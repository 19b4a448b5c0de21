// The dynamic built-ins must be as hard as TUM's walking sequences: movers cover at least 25 %
// of the image in at least a third of the frames, and come close to the camera at times.
// Market: most walkers are partly hidden by others.
#include <gtest/gtest.h>

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

TEST(ScenarioDifficulty, OfficeStaticHasNoMovers) {
  Simulator sim(load_scenario("office-static"));
  EXPECT_TRUE(sim.world().movers().empty());
  EXPECT_GE(sim.world().objects().size(), 5u);
}

}  // namespace
}  // namespace kestrel::sim
