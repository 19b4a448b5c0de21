#pragma once
// A simulated world and run, as read from a scenario YAML file (config/scenarios/*.yaml
// documents every key). Built-in scenarios are such files, embedded at build time.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/calibration.hpp"
#include "sim/procedural_texture.hpp"
#include "sim/spline_trajectory.hpp"

namespace kestrel::sim {

struct SensorSpec {
  bool noise = true;              // false: exact colour and depth (for consistency tests)
  double rgb_noise = 2.0;         // sigma, grey levels
  double depth_sigma_z2 = 0.003;  // sigma = a z^2 metres (RealSense D455-like)
  double depth_min = 0.4;         // metres; nearer is a hole
  double depth_max = 8.0;         // metres; farther is a hole
  double edge_holes = 0.5;        // probability a pixel at a depth discontinuity is a hole
  int motion_blur = 0;            // sub-frames averaged over exposure_time (0 or 1: off)
  double exposure_time = 0.01;    // seconds
  double jitter = 0.0;            // sigma of frame stamp jitter, seconds
  double drop_rate = 0.0;         // fraction of frames dropped
  std::vector<std::array<double, 2>> exposure;  // [t, gain] steps; gain 1 before the first
};

struct StaticBoxSpec {  // walls, buildings, pillars: scenery without a label
  Vec3 center = Vec3::Zero();
  Vec3 size = Vec3::Ones();
  double yaw = 0.0;
  TextureSpec texture;
  bool inward = false;  // a room seen from inside
};

struct ObjectSpec {  // a labelled static object with a known 3D box
  std::string label;
  Vec3 center = Vec3::Zero();  // box centre, world
  Vec3 size = Vec3::Ones();
  double yaw = 0.0;
  TextureSpec texture;
  std::string photo;  // a vehicle cut-out (photo_cutouts.hpp): a parked car shaped like it
};

struct LightZone {  // a region where surfaces get less (or more) light: a shadowed corridor
  Vec3 min = Vec3::Zero();
  Vec3 max = Vec3::Zero();
  double gain = 1.0;
};

struct MoverSpec {
  std::string type = "person";  // person | vehicle | box | chair | spin | bird
  std::string label = "person";
  int sprite = 0;                   // person: which cut-out (person_sprites.hpp)
  std::string photo;                // vehicle: cut-out for its sides; empty: painted box
  std::vector<Vec3> path;           // way points (z = ground; bird: flying height)
  double speed = 1.2;               // m/s along the path
  double start = 0.0;               // s: static before
  double stop = -1.0;               // s: static after (negative: never)
  std::string mode = "loop";        // loop | pingpong | once
  double height = 1.75;             // person
  Vec3 size = Vec3(0.5, 0.5, 0.5);  // vehicle/box/chair/spin; bird: length, wingspan, body
  double flap_hz = 4.0;             // bird: wing beats per second
  Vec3 center = Vec3::Zero();       // spin: where it turns
  double yaw = 0.0;                 // spin: initial yaw
  double rate = 1.0;                // spin: rad/s
  TextureSpec texture;
};

struct TrajectorySpec {
  std::string kind = "handheld";  // handheld | ugv | uav
  double segment_time = 1.0;
  int laps = 1;
  std::vector<TrajectoryKnot> knots;
  double wobble_position = 0.0;   // metres
  double wobble_rotation = 0.0;   // radians
  double wobble_frequency = 0.8;  // Hz
  // Heights (metres, world z of the body): no wobble at or below the first, full from the
  // second (sim::Wobble). Equal: full everywhere.
  double wobble_fade_still = 0.0;
  double wobble_fade_full = 0.0;
};

struct Scenario {
  std::string name;
  std::string source;  // file it came from, for errors
  std::string yaml;    // the exact parameters (after overrides), written as scenario.yaml
  std::uint64_t seed = 1;
  double duration = -1.0;  // seconds; negative: the trajectory's length
  Calibration calib;
  SensorSpec sensor;
  std::array<int, 3> sky_top{120, 160, 215};     // RGB
  std::array<int, 3> sky_bottom{210, 220, 230};  // RGB
  bool has_ground = false;
  Vec3 ground_center = Vec3::Zero();
  std::array<double, 2> ground_size{40, 40};
  TextureSpec ground_texture;
  // Turn and shade each texture repeat of the ground at random, so the ground is not periodic:
  // a plaza of identical 3 m patches lets a tracker slip by exactly one patch.
  bool ground_shuffle = false;
  std::vector<StaticBoxSpec> boxes;
  std::vector<ObjectSpec> objects;
  std::vector<LightZone> lights;
  std::vector<MoverSpec> movers;
  TrajectorySpec trajectory;
  std::string assets;  // folder holding tum_fr3/ and images/ (the shared data)
};

struct ScenarioOverrides {
  long long seed = -1;     // negative: keep the file's
  double duration = -1.0;  // negative: keep
  bool no_movers = false;
};

// Parses scenario YAML text; errors name `name_for_errors`, the line and the field.
Scenario parse_scenario(const std::string& text, const std::string& name_for_errors,
                        const ScenarioOverrides& overrides = {});
// NAME of a built-in scenario, or a path to a YAML file.
Scenario load_scenario(const std::string& name_or_path, const ScenarioOverrides& overrides = {});

// The shared data folder: $KESTREL_SHARED/data, else ../shared/data beside the source tree.
std::string default_assets_dir();

}  // namespace kestrel::sim
