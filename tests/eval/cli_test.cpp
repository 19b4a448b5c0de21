// `kestrel eval` end to end: the built CLI on evo's KITTI files.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>

#include "tests/test_paths.hpp"

namespace {

namespace fs = std::filesystem;

int run(const std::string& args, const fs::path& log) {
  const std::string cmd = (kestrel::test::build_dir() / "kestrel").string() + " " + args + " > " +
                          log.string() + " 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string evo(const std::string& name) {
  return kestrel::test::shared_data("evo/" + name).string();
}

TEST(EvalCli, ApeKittiWritesEvoFigures) {
  const fs::path dir = kestrel::test::temp_dir("eval_cli_ape");
  const fs::path json = dir / "ape.json";
  const int rc = run("eval ape " + evo("KITTI_00_gt.txt") + " " + evo("KITTI_00_ORB.txt") +
                         " --align se3 --json " + json.string(),
                     dir / "log.txt");
  ASSERT_EQ(rc, 0) << slurp(dir / "log.txt");
  const auto j = nlohmann::json::parse(slurp(json));
  EXPECT_NEAR(j.at("rmse").get<double>(), 1.3034497145650266, 1.3034497145650266 * 1e-9);
  EXPECT_NEAR(j.at("sse").get<double>(), 7715.073440292808, 7715.073440292808 * 1e-9);
  EXPECT_EQ(j.at("pairs").get<int>(), 4541);
  for (const char* key : {"mean", "median", "std", "min", "max"}) EXPECT_TRUE(j.contains(key));
  const std::string table = slurp(dir / "log.txt");
  EXPECT_NE(table.find("rmse\t1.303450"), std::string::npos) << table;
  EXPECT_NE(table.find("SE(3) Umeyama"), std::string::npos) << table;
}

TEST(EvalCli, RpeKittiMeters) {
  const fs::path dir = kestrel::test::temp_dir("eval_cli_rpe");
  const fs::path json = dir / "rpe.json";
  const int rc = run("eval rpe " + evo("KITTI_00_gt.txt") + " " + evo("KITTI_00_SPTAM.txt") +
                         " --delta 10 --unit m --json " + json.string(),
                     dir / "log.txt");
  ASSERT_EQ(rc, 0) << slurp(dir / "log.txt");
  const auto j = nlohmann::json::parse(slurp(json));
  EXPECT_NEAR(j.at("rmse").get<double>(), 0.27607109043606004, 0.27607109043606004 * 1e-9);
}

TEST(EvalCli, KittiWithTimesFilesAssociatesByStamp) {
  const fs::path dir = kestrel::test::temp_dir("eval_cli_times");
  const std::string times = evo("KITTI_00_gt_times.txt");
  const int rc = run("eval ape " + evo("KITTI_00_gt.txt") + " " + evo("KITTI_00_ORB.txt") +
                         " --ref-times " + times + " --est-times " + times +
                         " --align se3 --json " + (dir / "ape.json").string(),
                     dir / "log.txt");
  ASSERT_EQ(rc, 0) << slurp(dir / "log.txt");
  const auto j = nlohmann::json::parse(slurp(dir / "ape.json"));
  EXPECT_EQ(j.at("pairs").get<int>(), 4541);
  EXPECT_NEAR(j.at("rmse").get<double>(), 1.3034497145650266, 1.3034497145650266 * 1e-9);
}

TEST(EvalCli, PlotWritesPng) {
  const fs::path dir = kestrel::test::temp_dir("eval_cli_plot");
  const fs::path png = dir / "ape.png";
  const int rc = run("eval ape " + evo("freiburg1_xyz-groundtruth.txt") + " " +
                         evo("freiburg1_xyz-rgbdslam.txt") + " --align se3 --plot " + png.string(),
                     dir / "log.txt");
  ASSERT_EQ(rc, 0) << slurp(dir / "log.txt");
  const std::string bytes = slurp(png);
  ASSERT_GT(bytes.size(), 1000u);
  EXPECT_EQ(bytes.substr(1, 3), "PNG");
}

TEST(EvalCli, BadFlagsExitWithTwo) {
  const fs::path dir = kestrel::test::temp_dir("eval_cli_bad");
  const std::string files = evo("KITTI_00_gt.txt") + " " + evo("KITTI_00_ORB.txt");
  EXPECT_EQ(run("eval ape " + files + " --bogus", dir / "a.txt"), 2);
  EXPECT_EQ(run("eval ape " + files + " --align sideways", dir / "b.txt"), 2);
  EXPECT_EQ(run("eval ape " + files + " --max-diff -1", dir / "c.txt"), 2);
  EXPECT_EQ(run("eval ape " + files + " --align se3 --align-origin", dir / "d.txt"), 2);
  EXPECT_EQ(run("eval rpe " + files + " --unit parsecs", dir / "e.txt"), 2);
  EXPECT_EQ(run("eval ape /nonexistent.txt " + evo("KITTI_00_ORB.txt"), dir / "f.txt"), 2);
  const std::string err = slurp(dir / "b.txt");
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;  // one line
}

TEST(EvalCli, BadFileContentExitsNonZeroNamingTheLine) {
  const fs::path dir = kestrel::test::temp_dir("eval_cli_content");
  const fs::path bad = dir / "bad.txt";
  std::ofstream(bad) << "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 zero 1\n";
  EXPECT_EQ(run("eval ape " + bad.string() + " " + bad.string(), dir / "log.txt"), 1);
  EXPECT_NE(slurp(dir / "log.txt").find(bad.string() + ":2"), std::string::npos);
}

}  // namespace
