// frames.csv, the per-frame record of a run: one row per reported frame, every column the header
// names, and the local map's size and points in view beside the inliers they bound; the time the
// run's files took to write, and their count and bytes, in the summary.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/run_job.hpp"
#include "sim/live_source.hpp"
#include "sim/scenario.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::pipeline {
namespace {

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  for (std::string cell; std::getline(ss, cell, ',');) out.push_back(cell);
  return out;
}

TEST(FramesCsv, EveryTrackedRowHasItsLocalMapAndThePointsInView) {
  sim::ScenarioOverrides over;
  over.duration = 1.0;
  sim::LiveSource source(sim::load_scenario("office-static", over));
  RunOptions opt;
  opt.detector = "none";
  opt.progress = false;
  opt.strip_frames = 0;
  opt.loop_closing = false;
  opt.out_dir = test::temp_dir("frames-csv").string();
  const RunSummary s = run_sequence(source, opt);

  std::ifstream in(opt.out_dir + "/frames.csv");
  ASSERT_TRUE(in) << opt.out_dir;
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  const std::vector<std::string> header = split(line);
  ASSERT_EQ(header.size(), 16u) << line;
  EXPECT_EQ(header[4], "inliers");
  EXPECT_EQ(header[14], "local points");
  EXPECT_EQ(header[15], "visible points");

  std::size_t rows = 0, tracked = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> c = split(line);
    ASSERT_EQ(c.size(), header.size()) << line;
    ++rows;
    if (rows == 1 || c[1] != "ok") continue;  // the first frame starts the map
    ++tracked;
    const int inliers = std::stoi(c[4]), local = std::stoi(c[14]), visible = std::stoi(c[15]);
    EXPECT_GT(inliers, 0) << line;
    EXPECT_GE(local, visible) << line;
    EXPECT_GE(local, inliers) << line;
    // The inliers were matched among points in view (at the final pose, or at the first pass's
    // when the second found fewer): the points in view cannot be a small part of them.
    EXPECT_GE(visible, inliers / 2) << line;
  }
  EXPECT_EQ(rows, s.frames);
  EXPECT_GE(tracked, s.frames - 2);

  // The write itself is timed and the folder's files counted (summary.json among them).
  std::size_t files = 0;
  std::uintmax_t bytes = 0;
  for (const auto& e : std::filesystem::directory_iterator(opt.out_dir)) {
    ++files;
    if (e.path().filename() != "summary.json") bytes += e.file_size();
  }
  EXPECT_GT(s.outputs_write_s, 0.0);
  EXPECT_EQ(s.outputs_files, files - 1);  // counted before summary.json was written
  EXPECT_EQ(s.outputs_bytes, bytes);
  for (const char* f : {"trajectory.txt", "map.bin", "cloud.ply", "map.pgm", "objects.json"})
    EXPECT_TRUE(std::filesystem::exists(opt.out_dir + "/" + f)) << f;
  const auto j = nlohmann::json::parse(std::ifstream(opt.out_dir + "/summary.json"));
  EXPECT_DOUBLE_EQ(j["outputs_write_s"].get<double>(), s.outputs_write_s);
  EXPECT_EQ(j["outputs_files"].get<std::size_t>(), s.outputs_files);
  std::filesystem::remove_all(opt.out_dir);
}

}  // namespace
}  // namespace kestrel::pipeline
