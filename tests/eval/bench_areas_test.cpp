// `kestrel bench --tiny --only <areas>`: every area beyond accuracy runs on tiny inputs, its
// table prints and its JSON holds the figures the issues name, each a finite number.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/test_paths.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Every number under `j` is finite; the path of the first that is not, else "".
std::string first_non_finite(const json& j, const std::string& path) {
  if (j.is_number_float() && !std::isfinite(j.get<double>())) return path;
  if (j.is_object() || j.is_array()) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      const std::string key = j.is_object() ? it.key() : std::to_string(&*it - &*j.begin());
      if (auto bad = first_non_finite(*it, path + "/" + key); !bad.empty()) return bad;
    }
  }
  return "";
}

double number_at(const json& j, const std::string& pointer) {
  const json::json_pointer p(pointer);
  EXPECT_TRUE(j.contains(p)) << pointer;
  if (!j.contains(p) || !j.at(p).is_number()) return std::nan("");
  return j.at(p).get<double>();
}

TEST(BenchAreas, TinyRunOfEveryAreaWritesFiniteFigures) {
  const fs::path dir = kestrel::test::temp_dir("bench_areas");
  const fs::path out = dir / "bench.json", log = dir / "log.txt";
  const std::string cmd =
      (kestrel::test::build_dir() / "kestrel").string() +
      " bench --tiny --only dynamic,evaluation,imu,objects,telemetry,video,endurance,memory"
      " --json " +
      out.string() + " --work " + (dir / "work").string() + " > " + log.string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(out);
  const json j = json::parse(in);
  // The live run's own outputs stay in the work folder.
  const fs::path live = j["endurance"]["outputs"].get<std::string>();
  EXPECT_EQ(live, dir / "work" / "endurance");
  EXPECT_TRUE(fs::exists(live / "trajectory.txt"));
  EXPECT_TRUE(fs::exists(live / "frames.csv"));
  EXPECT_EQ(first_non_finite(j, ""), "");
  EXPECT_FALSE(j.contains("runs")) << "accuracy ran though not asked for";

  // Evaluation reproduces evo's stored KITTI figures (the 1e-9 check lives in evo_reference).
  for (const char* p : {"/evaluation/kitti_00/orb/ape_se3_rmse/rel_error",
                        "/evaluation/kitti_00/orb/rpe_10m_rmse/rel_error",
                        "/evaluation/kitti_00/sptam/ape_se3_rmse/rel_error",
                        "/evaluation/kitti_00/sptam/rpe_10m_rmse/rel_error"})
    EXPECT_LT(number_at(j, p), 1e-9) << p;
  EXPECT_NEAR(number_at(j, "/evaluation/dynaslam_tum_ate/fr3_walk_xyz/ours"), 0.016314, 1e-5);
  EXPECT_EQ(number_at(j, "/evaluation/dynaslam_tum_ate/fr3_walk_xyz/pairs"), 757);

  // IMU: the midpoint scheme is second order, far under a millimetre over 0.5 s at 200 Hz.
  EXPECT_GT(number_at(j, "/imu/preintegration/windows"), 0);
  EXPECT_LT(number_at(j, "/imu/preintegration/position_error_m_max"), 1e-3);
  EXPECT_LT(number_at(j, "/imu/static_init_euroc_v1_01_micro/gyro_bias_error_radps"), 2e-3);
  EXPECT_LT(number_at(j, "/imu/static_init_euroc_v1_01_micro/gravity_angle_error_deg"), 1.0);

  for (const char* key :
       {"recall", "precision", "center_error_median_m", "size_error_median", "class_correct",
        "grid_iou", "dynamic_residue_rejection", "dynamic_residue_off"}) {
    const double v = number_at(j, std::string("/objects/cafe/") + key);
    EXPECT_GE(v, 0.0) << key;
  }
  EXPECT_GT(number_at(j, "/objects/cafe/truth"), 0);

  EXPECT_GT(number_at(j, "/telemetry/pose_bytes_per_s"), 0);
  EXPECT_GT(number_at(j, "/telemetry/total_bytes_per_s_per_agent"),
            number_at(j, "/telemetry/pose_bytes_per_s"));
  // The link over a real mosquitto (skipped, with its reason, where none is installed).
  ASSERT_TRUE(j["telemetry"].contains("link"));
  if (j["telemetry"]["link"].value("status", "") == "ok") {
    EXPECT_GT(number_at(j, "/telemetry/link/pose_latency_ms/p50"), 0);
    EXPECT_GE(number_at(j, "/telemetry/link/pose_latency_ms/p99"),
              number_at(j, "/telemetry/link/pose_latency_ms/p50"));
    EXPECT_GT(number_at(j, "/telemetry/link/command_rtt_ms/p50"), 0);
    ASSERT_EQ(j["telemetry"]["link"]["scale"].size(), 2u);  // --tiny: 1 and 5 agents
    EXPECT_GT(number_at(j, "/telemetry/link/scale/1/wire_in_kB_per_s"),
              number_at(j, "/telemetry/link/scale/0/wire_in_kB_per_s"));
    EXPECT_GT(number_at(j, "/telemetry/link/scale/1/messages_received"), 0);
  }

  ASSERT_TRUE(j.contains("video"));
  if (j["video"].value("status", "") == "ok") {
    for (const char* size : {"640x480", "1280x720"}) {
      EXPECT_GT(number_at(j, std::string("/video/") + size + "/encode_ms_median"), 0) << size;
      EXPECT_GT(number_at(j, std::string("/video/") + size + "/kbps"), 0) << size;
    }
  }
  EXPECT_GT(number_at(j, "/memory/peak_rss_mib"), 0);

  // Endurance: 3 s of market live at real-time pace (91 frames), memory sampled along the way.
  EXPECT_EQ(number_at(j, "/endurance/frames"), 91);
  EXPECT_GE(number_at(j, "/endurance/wall_seconds"), 3.0);  // paced: never faster than the sensor
  // Live: frames that arrive while the tracker is busy are dropped; the fed ones are tracked.
  const double fed = number_at(j, "/endurance/frames") - number_at(j, "/endurance/dropped");
  EXPECT_GT(fed, 0);
  EXPECT_GT(number_at(j, "/endurance/tracked"), 0.5 * fed);
  EXPECT_GT(number_at(j, "/endurance/frame_latency_ms/p99"), 0);
  EXPECT_GE(number_at(j, "/endurance/frame_latency_ms/p99"),
            number_at(j, "/endurance/frame_latency_ms/p50"));
  EXPECT_GT(number_at(j, "/endurance/rss_mib_end"), 0);
  EXPECT_GE(number_at(j, "/endurance/rss_mib_peak"), number_at(j, "/endurance/rss_mib_end"));
  EXPECT_GE(j["endurance"]["rss_samples_s_mib"].size(), 4u);
  EXPECT_GT(number_at(j, "/endurance/keyframes"), 0);
  EXPECT_GT(number_at(j, "/endurance/map_points"), 0);

  // Dynamic: every row of issue 5 on the (tiny) cafe, and the unknown-class mover it chose.
  for (const char* row :
       {"hybrid+yolo", "hybrid+oracle", "hybrid+oracle-fn20", "hybrid+oracle, unknown-class mover",
        "detection+yolo", "geometry", "off", "hybrid+yolo, k-5"}) {
    const std::string p = std::string("/dynamic/cafe/rows/") + row;
    EXPECT_GE(number_at(j, p + "/dynamic_removed_percent"), 0.0) << row;
    EXPECT_GT(number_at(j, p + "/dynamic_features"), 0) << row;
  }
  EXPECT_EQ(number_at(j, "/dynamic/cafe/rows/off/dynamic_removed_percent"), 0.0);
  EXPECT_GT(number_at(j, "/dynamic/cafe/unknown_mover/instance"), 0);
  // The mover's features that reach tracking: fewer when the detector knows its class. Counts,
  // not percentages: with its class known, the movers' silhouettes leave it few features to
  // judge at all (dynamic/mover_silhouette.hpp).
  const auto unknown_mover_kept = [&](const std::string& row) {
    const std::string p = "/dynamic/cafe/rows/" + row + "/";
    return number_at(j, p + "unknown_mover_features") *
           (1.0 - number_at(j, p + "unknown_mover_removed_percent") / 100.0);
  };
  EXPECT_LT(unknown_mover_kept("hybrid+oracle"),
            unknown_mover_kept("hybrid+oracle, unknown-class mover"));

  std::ifstream text(log);
  const std::string printed((std::istreambuf_iterator<char>(text)), {});
  for (const char* table : {"## Dynamic features", "## Evaluation", "## IMU", "## Objects",
                            "## Telemetry", "## Video", "## Memory"})
    EXPECT_NE(printed.find(table), std::string::npos) << table;
}

// --seeds: each accuracy scene is drawn again with the next seeds, and a table gives each
// scene's median and range over the draws.
TEST(BenchAreas, AccuracyOverSeveralDrawsOfTheWorld) {
  const fs::path dir = kestrel::test::temp_dir("bench_seeds");
  const fs::path out = dir / "bench.json", log = dir / "log.txt";
  const std::string cmd = (kestrel::test::build_dir() / "kestrel").string() +
                          " bench --tiny --seeds 2 --only accuracy --json " + out.string() + " > " +
                          log.string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(out);
  const json j = json::parse(in);
  ASSERT_EQ(j["scenes"].size(), 2u);
  const long long s0 = j["scenes"][0]["seed"], s1 = j["scenes"][1]["seed"];
  EXPECT_EQ(s1, s0 + 1);
  ASSERT_EQ(j["runs"].size(), 4u);  // two modes on each draw
  ASSERT_EQ(j["accuracy_over_seeds"].size(), 2u);
  for (const json& g : j["accuracy_over_seeds"]) {
    ASSERT_EQ(g["ape_rmse_m"].size(), 2u) << g.dump();
    const double a = g["ape_rmse_m"][0], b = g["ape_rmse_m"][1];
    // Two draws are two worlds: not the same run twice.
    EXPECT_NE(a, b);
    EXPECT_DOUBLE_EQ(g["ape_rmse_min_m"].get<double>(), std::min(a, b));
    EXPECT_DOUBLE_EQ(g["ape_rmse_max_m"].get<double>(), std::max(a, b));
    EXPECT_NEAR(g["ape_rmse_median_m"].get<double>(), 0.5 * (a + b), 1e-12);
  }
  std::ifstream lin(log);
  const std::string printed((std::istreambuf_iterator<char>(lin)),
                            std::istreambuf_iterator<char>());
  EXPECT_NE(printed.find("## Accuracy over 2 draws"), std::string::npos);
  EXPECT_NE(printed.find("cafe seed " + std::to_string(s1)), std::string::npos);
}

TEST(BenchAreas, UnknownAreaIsAnError) {
  const fs::path dir = kestrel::test::temp_dir("bench_areas_bad");
  const std::string cmd = (kestrel::test::build_dir() / "kestrel").string() +
                          " bench --only bogus --json " + (dir / "b.json").string() + " > " +
                          (dir / "log.txt").string() + " 2>&1";
  EXPECT_NE(std::system(cmd.c_str()), 0);
}

}  // namespace
