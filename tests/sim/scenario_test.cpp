// Scenario files: every built-in parses, overrides apply, and bad input names file, line, field.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/error.hpp"
#include "sim/builtin_scenarios.hpp"
#include "sim/scenario.hpp"
#include "sim/world.hpp"

namespace kestrel::sim {
namespace {

TEST(Scenario, EveryBuiltInParses) {
  const auto names = builtin_scenario_names();
  for (const char* expected :
       {"office-static", "cafe", "market", "uav-zigzag", "ugv-loop", "corridor-dark"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end()) << expected;
  }
  for (const auto& name : names) {
    const Scenario s = load_scenario(name);
    EXPECT_EQ(s.name, name);
    EXPECT_FALSE(s.trajectory.knots.empty());
    EXPECT_EQ(s.calib.camera.width, 640);
    EXPECT_EQ(s.calib.camera.height, 480);
    EXPECT_DOUBLE_EQ(s.calib.fps, 30.0);
    EXPECT_DOUBLE_EQ(s.calib.imu.rate_hz, 200.0);
  }
}

TEST(Scenario, OverridesReachTheParametersAndTheWrittenYaml) {
  ScenarioOverrides ov;
  ov.seed = 77;
  ov.duration = 1.5;
  ov.no_movers = true;
  const Scenario s = load_scenario("cafe", ov);
  EXPECT_EQ(s.seed, 77u);
  EXPECT_DOUBLE_EQ(s.duration, 1.5);
  EXPECT_TRUE(s.movers.empty());
  EXPECT_NE(s.yaml.find("seed: 77"), std::string::npos);
  // The written parameters parse back to the same scenario.
  const Scenario again = parse_scenario(s.yaml, "again");
  EXPECT_EQ(again.seed, 77u);
  EXPECT_TRUE(again.movers.empty());
  EXPECT_EQ(again.objects.size(), s.objects.size());
}

std::string error_of(const std::string& text) {
  try {
    parse_scenario(text, "bad.yaml");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Scenario, BadInputNamesFileLineAndField) {
  const std::string base = "trajectory:\n  waypoints: [[0, 0, 1, 0]]\n";
  EXPECT_NE(error_of(base + "camera: {fx: -3}\n").find("bad.yaml:3: field 'camera.fx'"),
            std::string::npos)
      << error_of(base + "camera: {fx: -3}\n");
  EXPECT_NE(error_of(base + "movers:\n  - {type: dragon, path: [[0, 0]]}\n")
                .find("bad.yaml:4: field 'movers[0].type'"),
            std::string::npos);
  EXPECT_NE(error_of(base + "sensr: {}\n").find("field 'sensr': unknown key"), std::string::npos);
  EXPECT_NE(error_of(base + "world:\n  ground: {shuffle: sometimes}\n")
                .find("field 'world.ground.shuffle'"),
            std::string::npos)
      << error_of(base + "world:\n  ground: {shuffle: sometimes}\n");
  EXPECT_NE(
      error_of("trajectory:\n  waypoints: [[0, 0, 1]]\n").find("field 'trajectory.waypoints[0]'"),
      std::string::npos);
  EXPECT_NE(error_of(base + "world:\n  objects:\n    - {center: [0, 0, 0]}\n")
                .find("world.objects[0].label"),
            std::string::npos);
  const std::string fade =
      "trajectory:\n  waypoints: [[0, 0, 1, 0]]\n  wobble: {fade_heights: [1.3, 0.3]}\n";
  EXPECT_NE(error_of(fade).find("bad.yaml:3: field 'trajectory.wobble.fade_heights'"),
            std::string::npos)
      << error_of(fade);
  EXPECT_EQ(parse_scenario("trajectory:\n  waypoints: [[0, 0, 1, 0]]\n  wobble: {fade_heights: "
                           "[0.3, 1.3]}\n",
                           "good.yaml")
                .trajectory.wobble_fade_full,
            1.3);
  EXPECT_THROW(load_scenario("no-such-scenario"), Error);
  // Counts are whole numbers in range: 1e12 pixels wide once overflowed the int it is cast to.
  for (const char* count : {"camera: {width: 1e12}\n", "camera: {height: 0}\n",
                            "camera: {width: 640.5}\n", "sensor: {motion_blur: -2}\n"}) {
    EXPECT_NE(error_of(base + count).find("must be a whole number in"), std::string::npos)
        << error_of(base + count);
  }
  EXPECT_NE(error_of(base + "camera: {width: 1e12}\n").find("bad.yaml:3: field 'camera.width'"),
            std::string::npos);
  EXPECT_NE(error_of(base + "movers:\n  - {type: person, sprite: -1, path: [[0, 0]]}\n")
                .find("field 'movers[0].sprite'"),
            std::string::npos);
  // A vehicle photo must be one of the cut-outs, and only vehicles carry one.
  const std::string bad_photo =
      error_of(base + "movers:\n  - {type: vehicle, photo: car-purple, path: [[0, 0]]}\n");
  EXPECT_NE(bad_photo.find("bad.yaml:4: field 'movers[0].photo'"), std::string::npos) << bad_photo;
  EXPECT_NE(bad_photo.find("car-red-wagon"), std::string::npos) << "lists the known cut-outs";
  EXPECT_NE(error_of(base + "movers:\n  - {type: box, photo: car-red-wagon, path: [[0, 0]]}\n")
                .find("field 'movers[0].photo'"),
            std::string::npos);
  EXPECT_NE(error_of(base + "world:\n  objects:\n    - {label: car, photo: person-blue-jacket}\n")
                .find("field 'world.objects[0].photo'"),
            std::string::npos);
}

// The photos are read at run time from the shared folder: a missing one is an error that
// names the file, for people and for vehicles.
TEST(Scenario, MissingPhotoNamesTheFile) {
  const auto dir = std::filesystem::temp_directory_path() / "kestrel_no_assets";
  std::filesystem::create_directories(dir / "images");
  const std::string head =
      "assets: " + dir.string() + "\ntrajectory:\n  waypoints: [[0, 0, 1, 0]]\n";
  try {
    World w(parse_scenario(head + "movers:\n  - {type: vehicle, photo: car-white-pickup, "
                                  "path: [[0, 0]]}\n",
                           "v.yaml"));
    ADD_FAILURE() << "no error for a missing photo";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "images" / "dog.jpg").string()), std::string::npos)
        << e.what();
  }
  try {
    World w(parse_scenario(head + "movers:\n  - {type: person, path: [[0, 0]]}\n", "p.yaml"));
    ADD_FAILURE() << "no error for missing person photos";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir.string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace kestrel::sim
