// The object database and the clean maps on simulated worlds (ground-truth poses and boxes):
// the figures issue 6 asks for, printed so the report can quote them.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>

#include "tests/semantic/sim_object_run.hpp"

using namespace kestrel;

namespace {

void print(const std::string& name, const test::SimObjectScores& s) {
  std::printf(
      "[%s] %d keyframes: recall %.2f (%d/%d), precision %.2f (%d reported), class %.2f, "
      "centre err median %.3f m, size err median %.2f, grid IoU %.2f, residue %.4f, "
      "update ms median: objects %.2f, maps %.2f\n",
      name.c_str(), s.keyframes, s.recall, s.matched, s.truth, s.precision, s.reported,
      s.class_correct, s.center_error_median, s.size_error_median, s.grid_iou, s.dynamic_residue,
      s.object_ms_median, s.map_ms_median);
  for (const auto& l : s.lines) std::printf("    %s\n", l.c_str());
}

}  // namespace

// Regression guards at the figures measured when this landed (cafe, ground-truth poses and
// boxes, every 10th frame): recall 0.83, precision 0.83, centre error median 0.26 m, size error
// median 0.06, grid IoU 0.78. Issue 6 asks for recall and precision >= 0.9 and centre error
// <= 0.10 m; the gap is the one-sided view of objects 5-8 m away (depth sigma 0.003 z^2, about
// 15 cm at 7 m) and a chair tucked under its table that joins the table's cluster.
TEST(SimObjects, CafeObjectsAndGridMatchTheWorld) {
  test::SimObjectRunOptions o;
  o.scenario = "cafe";
  o.keyframe_every = 10;
  if (const char* out = std::getenv("KESTREL_SIM_OUT")) o.out_dir = out;
  const auto s = test::run_sim_objects(o);
  print("cafe", s);
  EXPECT_GE(s.truth, 6);
  EXPECT_GE(s.recall, 0.8);
  EXPECT_GE(s.precision, 0.8);
  EXPECT_GE(s.class_correct, 0.8);
  EXPECT_LE(s.center_error_median, 0.30);
  EXPECT_LE(s.size_error_median, 0.20);
  EXPECT_GE(s.grid_iou, 0.7);
  EXPECT_LE(s.dynamic_residue, 0.01);
}

// Other scenarios on request (KESTREL_SIM_SCENARIOS="market ugv-loop"): figures for the report.
TEST(SimObjects, ScenariosOnRequest) {
  const char* names = std::getenv("KESTREL_SIM_SCENARIOS");
  if (!names) GTEST_SKIP() << "set KESTREL_SIM_SCENARIOS to run";
  std::istringstream in(names);
  for (std::string name; in >> name;) {
    test::SimObjectRunOptions o;
    o.scenario = name;
    const auto s = test::run_sim_objects(o);
    print(name, s);
    EXPECT_GT(s.keyframes, 0);
    o.mask_movers = false;
    print(name + ", movers not masked", test::run_sim_objects(o));
  }
}
