#include "eval/report/run_report.hpp"

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "eval/trajectory_evaluation.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::report {
namespace {

Trajectory circle(double radius, double wobble) {
  Trajectory t;
  for (int i = 0; i < 100; ++i) {
    const double a = 0.06 * i;
    const Vec3 p(radius * std::cos(a) + wobble * std::sin(7 * a), radius * std::sin(a),
                 1.0 + 0.1 * std::sin(a) + wobble * std::cos(5 * a));
    t.push_back(100.0 + 0.1 * i, SE3(SO3(), p));
  }
  return t;
}

ReportInput sample_input() {
  ReportInput in;
  in.command_line = "kestrel run --dataset <x> & y";
  in.config_text = "camera:\n  fx: 525\n";
  in.version = "0.1.0";
  in.dataset = "kestrel:/tmp/seq";
  in.ground_truth = circle(2.0, 0.0);
  RunRecord a;
  a.name = "hybrid";
  a.estimate = circle(2.0, 0.05);
  a.frames = a.tracked = 100;
  a.has_removal = true;
  a.dynamic_total = 200, a.dynamic_removed = 150, a.static_total = 1000, a.static_kept = 950;
  a.tracking_ms_median = 20.0;
  a.stages = {{"features", 100, 10.0, 12.0, 15.0}, {"tracking", 100, 5.0, 6.0, 9.0}};
  a.counters = {{"frames.lost", 0}};
  RunRecord b = a;
  b.name = "off";
  b.estimate = circle(2.0, 0.2);
  b.dynamic_removed = 0;
  in.runs = {a, b};
  StripFrame f;
  f.caption = "frame 10";
  f.image = Image::allocate(64, 48, 3, PixelType::kU8);
  f.boxes = {{4, 4, 20, 40, "person", true}};
  f.points = {{30, 30, false}, {10, 10, true}};
  in.frames = {f};
  return in;
}

// The page without the base64 payloads (which may spell anything).
std::string without_data(std::string h) {
  for (auto at = h.find("base64,"); at != std::string::npos; at = h.find("base64,", at + 1)) {
    h.erase(at + 7, h.find('"', at) - at - 7);
  }
  return h;
}

// "nan" or "inf" as a printed number (not inside a word such as "Provenance").
bool has_non_finite(const std::string& h) {
  for (const char* word : {"nan", "inf"}) {
    for (auto at = h.find(word); at != std::string::npos; at = h.find(word, at + 1)) {
      const bool letter_before = at > 0 && std::isalpha(static_cast<unsigned char>(h[at - 1]));
      const bool letter_after =
          at + 3 < h.size() && std::isalpha(static_cast<unsigned char>(h[at + 3]));
      if (!letter_before && !letter_after) return true;
    }
  }
  return false;
}

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto at = s.find(what); at != std::string::npos; at = s.find(what, at + 1)) ++n;
  return n;
}

TEST(RunReport, HoldsPlotsTablesAndProvenance) {
  const std::string h = render_report(sample_input());
  EXPECT_EQ(h.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(h.find("</html>"), std::string::npos);
  // Top view, height and APE plots, plus the one frame of the strip.
  EXPECT_EQ(count(h, "<svg class=\"plot\""), 3u);
  EXPECT_NE(h.find("<table id=\"summary\""), std::string::npos);
  EXPECT_NE(h.find("<table id=\"removal\""), std::string::npos);
  EXPECT_NE(h.find("<td>75.0%</td>"), std::string::npos);  // 150 / 200 removed
  EXPECT_NE(h.find("<td>95.0%</td>"), std::string::npos);  // 950 / 1000 kept
  EXPECT_NE(h.find("<td>features</td>"), std::string::npos);
  EXPECT_NE(h.find("kestrel run --dataset &lt;x&gt; &amp; y"), std::string::npos);
  EXPECT_NE(h.find("fx: 525"), std::string::npos);
  EXPECT_NE(h.find("data:image/jpeg;base64,"), std::string::npos);
  EXPECT_NE(h.find(">person</text>"), std::string::npos);
  const std::string text = without_data(h);
  EXPECT_EQ(text.find("http"), std::string::npos);  // nothing to fetch
  EXPECT_FALSE(has_non_finite(text));
  EXPECT_EQ(h.find("id=\"grid\""), std::string::npos);  // no grid passed
}

TEST(RunReport, PlotsResidentMemoryWhenTheRunSampledIt) {
  ReportInput in = sample_input();
  EXPECT_EQ(render_report(in).find("Resident memory along the run"), std::string::npos);
  in.runs.front().memory_mib = {{0.0, 150.0}, {1.0, 180.0}, {2.0, 181.0}};
  const std::string h = render_report(in);
  EXPECT_NE(h.find("Resident memory along the run"), std::string::npos);
  EXPECT_EQ(count(h, "<svg class=\"plot\""), 4u);
  EXPECT_FALSE(has_non_finite(without_data(h)));
}

TEST(RunReport, ApeRmseIsTheEvaluatorsFigure) {
  const ReportInput in = sample_input();
  const std::string h = render_report(in);
  io::PoseSeries ref, est;
  for (std::size_t i = 0; i < in.ground_truth->size(); ++i) {
    ref.stamps.push_back(in.ground_truth->stamps[i]);
    ref.poses.push_back(in.ground_truth->poses[i].matrix());
    est.stamps.push_back(in.runs[1].estimate.stamps[i]);
    est.poses.push_back(in.runs[1].estimate.poses[i].matrix());
  }
  eval::ApeOptions opt;
  opt.alignment = eval::Alignment::kSe3;
  const double rmse = eval::evaluate_ape(ref, est, opt).stats.rmse;
  ASSERT_GT(rmse, 0.01);
  char buf[32];
  std::snprintf(buf, sizeof buf, "<td>%.4f</td>", rmse);
  EXPECT_NE(h.find(buf), std::string::npos) << buf;
}

TEST(RunReport, WithoutGroundTruthSaysSoAndDrawsNoApe) {
  ReportInput in = sample_input();
  in.ground_truth.reset();
  const std::string h = render_report(in);
  EXPECT_EQ(count(h, "<svg class=\"plot\""), 2u);
  EXPECT_NE(h.find("hybrid"), std::string::npos);
}

TEST(RunReport, DrawsTheGridWithObjectsAndPaths) {
  ReportInput in = sample_input();
  GridMap g;
  g.occupancy = Image::allocate(40, 20, 1, PixelType::kU8);
  g.resolution = 0.1;
  g.origin_x = -1.0, g.origin_y = -1.0;
  g.objects = {{"chair", 0.5, 0.5}};
  g.paths = {{{-0.5, -0.5}, {1.0, 0.5}, {2.5, 0.5}}};
  in.grid = g;
  const std::string h = render_report(in);
  EXPECT_NE(h.find("id=\"grid\""), std::string::npos);
  EXPECT_NE(h.find("data:image/png;base64,"), std::string::npos);
  EXPECT_NE(h.find(">chair</text>"), std::string::npos);
  // (0.5, 0.5) m is cell (15, 15) from the bottom-left: image row 20 - 15 = 5.
  EXPECT_NE(h.find("cx=\"15.000\" cy=\"5.000\""), std::string::npos);
}

TEST(RunReport, WriteReportNamesAnUnwritablePath) {
  try {
    write_report(sample_input(), "/nonexistent-dir/report.html");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/report.html"), std::string::npos);
  }
  const auto dir = test::temp_dir("run_report_write");
  write_report(sample_input(), (dir / "report.html").string());
  std::ifstream f(dir / "report.html");
  std::stringstream ss;
  ss << f.rdbuf();
  EXPECT_EQ(ss.str().rfind("<!DOCTYPE html>", 0), 0u);
}

}  // namespace
}  // namespace kestrel::report
