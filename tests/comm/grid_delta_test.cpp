// Occupancy-grid deltas: exact reconstruction, a delta costs the change not the map, and bad
// deltas leave the receiver's grid untouched.
#include <gtest/gtest.h>

#include <random>

#include "comm/codec.hpp"
#include "comm/grid_delta.hpp"

namespace kestrel::comm {
namespace {

GridState make_grid(std::uint32_t w, std::uint32_t h) {
  GridState g;
  g.width = w;
  g.height = h;
  g.resolution = 0.05;
  g.origin = {-10, -10};
  g.cells.assign(static_cast<std::size_t>(w) * h, 255);
  return g;
}

TEST(GridDelta, KeyframeThenDeltasReconstructExactly) {
  GridState agent = make_grid(400, 300);
  std::mt19937 rng(7);
  for (std::size_t i = 0; i < agent.cells.size(); ++i) {
    if (i % 400 < 200) agent.cells[i] = rng() % 3 == 0 ? 100 : 0;
  }
  agent.seq = 1;
  GridState station;
  const GridDeltaMsg key = make_grid_delta(GridState{}, agent, 1);
  EXPECT_EQ(key.base_seq, 0u);
  ASSERT_TRUE(apply_grid_delta(station, key));
  EXPECT_EQ(station.cells, agent.cells);

  for (int round = 0; round < 5; ++round) {
    GridState next = agent;
    next.seq = agent.seq + 1;
    for (int k = 0; k < 300; ++k)
      next.cells[rng() % next.cells.size()] = static_cast<std::uint8_t>(rng() % 101);
    const GridDeltaMsg delta = make_grid_delta(agent, next, round + 2);
    EXPECT_EQ(delta.base_seq, agent.seq);
    ASSERT_TRUE(apply_grid_delta(station, delta));
    EXPECT_EQ(station.cells, next.cells);
    EXPECT_EQ(station.seq, next.seq);
    agent = next;
  }
}

TEST(GridDelta, DeltaCostsTheChangeNotTheMap) {
  GridState base = make_grid(1000, 1000);
  std::mt19937 rng(3);
  for (auto& c : base.cells) c = rng() % 4 == 0 ? 100 : 0;  // hard to compress
  base.seq = 10;
  GridState next = base;
  next.seq = 11;
  for (int k = 0; k < 200; ++k) next.cells[(rng() % 1000) * 1000 + 400 + k % 20] = 100;
  const auto whole = encode(make_grid_delta(GridState{}, next, 0));
  const auto delta = encode(make_grid_delta(base, next, 0));
  std::printf("grid 1000x1000: keyframe %zu bytes, 200-cell delta %zu bytes\n", whole.size(),
              delta.size());
  EXPECT_LT(delta.size(), 2000u);
  EXPECT_GT(whole.size(), 50 * delta.size());
}

TEST(GridDelta, RejectsWrongBaseAndCorruptData) {
  GridState a = make_grid(50, 40);
  a.seq = 1;
  GridState b = a;
  b.seq = 2;
  b.cells[10] = 0;
  GridState station;
  ASSERT_TRUE(apply_grid_delta(station, make_grid_delta(GridState{}, a, 0)));
  GridDeltaMsg d = make_grid_delta(a, b, 0);
  GridState wrong = station;
  wrong.seq = 7;
  EXPECT_FALSE(apply_grid_delta(wrong, d));
  EXPECT_EQ(wrong.seq, 7u);
  GridDeltaMsg corrupt = d;
  corrupt.runs_zlib.assign(corrupt.runs_zlib.size(), 0x5a);
  const GridState before = station;
  EXPECT_FALSE(apply_grid_delta(station, corrupt));
  EXPECT_EQ(station.cells, before.cells);
  GridDeltaMsg bigger = d;
  bigger.width = 5000;
  bigger.height = 5000;
  EXPECT_FALSE(apply_grid_delta(station, bigger));
  ASSERT_TRUE(apply_grid_delta(station, d));
  EXPECT_EQ(station.cells, b.cells);
}

}  // namespace
}  // namespace kestrel::comm
