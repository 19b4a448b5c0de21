// `kestrel sim` output: the same scenario and seed write the same bytes, and the files hold the
// truth the simulator rendered.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "io/kestrel_sequence.hpp"
#include "sim/sequence_recorder.hpp"
#include "tests/test_paths.hpp"

namespace kestrel::sim {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Scenario short_cafe(long long seed) {
  ScenarioOverrides ov;
  ov.seed = seed;
  ov.duration = 0.5;
  return load_scenario("cafe", ov);
}

TEST(SequenceRecorder, SameScenarioAndSeedWriteIdenticalBytes) {
  const fs::path a = test::temp_dir("sim_seq_a"), b = test::temp_dir("sim_seq_b"),
                 c = test::temp_dir("sim_seq_c");
  Simulator sa(short_cafe(11)), sb(short_cafe(11)), sc(short_cafe(12));
  const RecordStats st = record_sequence(sa, a.string());
  record_sequence(sb, b.string());
  record_sequence(sc, c.string());
  EXPECT_EQ(st.frames, 16);
  std::size_t files = 0, differ_from_c = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), a);
    ASSERT_TRUE(fs::exists(b / rel)) << rel;
    EXPECT_EQ(slurp(e.path()), slurp(b / rel)) << rel;
    differ_from_c += !fs::exists(c / rel) || slurp(e.path()) != slurp(c / rel);
    ++files;
  }
  EXPECT_GE(files, 16u * 3 + 8);
  EXPECT_GT(differ_from_c, 16u);  // another seed: other noise, other bytes

  // The side files read back.
  const auto boxes = io::read_boxes((a / "boxes.csv").string());
  EXPECT_FALSE(boxes.empty());
  bool person = false;
  for (const auto& box : boxes) person |= box.label == "person" && box.moving;
  EXPECT_TRUE(person);
  const auto objects = io::read_objects((a / "objects.json").string());
  EXPECT_EQ(objects.size(), sa.world().objects().size());
  EXPECT_TRUE(fs::exists(a / "scenario.yaml"));
  EXPECT_TRUE(fs::exists(a / "calib.yaml"));
}

}  // namespace
}  // namespace kestrel::sim
