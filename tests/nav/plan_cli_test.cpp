// The `kestrel plan` command end to end (skipped when the CLI has not been built).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "maps/grid_io.hpp"
#include "tests/test_paths.hpp"

using namespace kestrel;

namespace {

int run(const std::string& cmd) {
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

}  // namespace

TEST(PlanCli, PrintsAndWritesThePathAndRefusesABlockedGoal) {
  const auto cli = test::build_dir() / "kestrel";
  if (!std::filesystem::exists(cli)) GTEST_SKIP() << "build/kestrel not built";
  const auto dir = test::temp_dir("nav-cli");
  maps::OccupancyGrid g(40, 20, 0.1, Vec2::Zero(), maps::kFree);
  for (int y = 0; y < 15; ++y) g.set({20, y}, maps::kOccupied);
  maps::write_map((dir / "map.yaml").string(), g);
  const std::string base = cli.string() + " plan --map " + (dir / "map.yaml").string();
  const auto out = dir / "path.txt";
  ASSERT_EQ(run(base + " --from 0.5,0.5 --to 3.5,0.5 --radius 0.1 --out " + out.string() + " > " +
                (dir / "stdout.txt").string()),
            0);
  std::ifstream in(out);
  std::string line;
  int rows = 0;
  double x = 0, y = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream(line) >> x >> y;
    ++rows;
  }
  EXPECT_GT(rows, 30);
  EXPECT_NEAR(x, 3.55, 1e-6);
  EXPECT_NEAR(y, 0.55, 1e-6);
  const auto err = dir / "stderr.txt";
  EXPECT_EQ(run(base + " --from 0.5,0.5 --to 2.05,0.5 2> " + err.string()), 2);
  std::stringstream ss;
  ss << std::ifstream(err).rdbuf();
  EXPECT_NE(ss.str().find("inside an obstacle"), std::string::npos) << ss.str();
}
