#include "sim/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "core/error.hpp"
#include "sim/builtin_scenarios.hpp"
#include "sim/photo_cutouts.hpp"

namespace kestrel::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;

// node[key], or a null node when the key is missing (a missing key's node throws when indexed).
YAML::Node sub(const YAML::Node& node, const char* key) {
  if (!node.IsDefined() || !node.IsMap()) return YAML::Node();
  const YAML::Node n = node[key];
  return n.IsDefined() ? n : YAML::Node();
}

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Node& n, const std::string& field,
                         const std::string& msg) const {
    throw Error::at(file_, n.IsDefined() ? n.Mark().line + 1 : 0, field, msg);
  }
  // Rejects keys the section does not know, so a typo is an error and not a silent default.
  void allow(const YAML::Node& map, const std::string& where,
             std::initializer_list<const char*> keys) const {
    if (!map.IsDefined() || map.IsNull()) return;
    if (!map.IsMap()) fail(map, where, "expected a mapping");
    std::set<std::string> ok(keys.begin(), keys.end());
    for (const auto& kv : map) {
      const std::string k = kv.first.as<std::string>();
      if (!ok.count(k)) fail(kv.first, where.empty() ? k : where + "." + k, "unknown key");
    }
  }
  double number(const YAML::Node& n, const std::string& field) const {
    try {
      const double v = n.as<double>();
      if (!std::isfinite(v)) fail(n, field, "not a finite number");
      return v;
    } catch (const YAML::Exception&) {
      fail(n, field, "expected a number");
    }
  }
  double get(const YAML::Node& map, const char* key, double def, const std::string& where) const {
    const YAML::Node n = sub(map, key);
    return !n.IsNull() ? number(n, where + key) : def;
  }
  double positive(const YAML::Node& map, const char* key, double def,
                  const std::string& where) const {
    const double v = get(map, key, def, where);
    if (!(v > 0.0)) fail(map[key], where + key, "must be > 0");
    return v;
  }
  // A whole number in [lo, hi]: a double outside int's range would make the cast undefined.
  int whole(const YAML::Node& map, const char* key, int def, int lo, int hi,
            const std::string& where) const {
    const double v = get(map, key, def, where);
    if (v != std::floor(v) || v < lo || v > hi) {
      fail(map[key], where + key,
           "must be a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return static_cast<int>(v);
  }
  double fraction(const YAML::Node& map, const char* key, double def,
                  const std::string& where) const {
    const double v = get(map, key, def, where);
    if (v < 0.0 || v > 1.0) fail(map[key], where + key, "must be in [0, 1]");
    return v;
  }
  std::string text(const YAML::Node& map, const char* key, const std::string& def,
                   const std::string& where) const {
    const YAML::Node n = sub(map, key);
    if (!n.IsDefined() || n.IsNull()) return def;
    if (!n.IsScalar()) fail(n, where + key, "expected text");
    return n.as<std::string>();
  }
  bool flag(const YAML::Node& map, const char* key, bool def, const std::string& where) const {
    const YAML::Node n = sub(map, key);
    if (!n.IsDefined() || n.IsNull()) return def;
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      fail(n, where + key, "expected true or false");
    }
  }
  std::vector<double> list(const YAML::Node& n, const std::string& field, std::size_t min_n,
                           std::size_t max_n) const {
    if (!n.IsSequence()) fail(n, field, "expected a list of numbers");
    if (n.size() < min_n || n.size() > max_n) {
      fail(n, field,
           "expected " + std::to_string(min_n) +
               (min_n == max_n ? "" : ".." + std::to_string(max_n)) + " numbers");
    }
    std::vector<double> out;
    for (std::size_t i = 0; i < n.size(); ++i)
      out.push_back(number(n[i], field + "[" + std::to_string(i) + "]"));
    return out;
  }
  Vec3 vec3(const YAML::Node& map, const char* key, const Vec3& def,
            const std::string& where) const {
    const YAML::Node n = sub(map, key);
    if (!n.IsDefined() || n.IsNull()) return def;
    const auto v = list(n, where + key, 3, 3);
    return Vec3(v[0], v[1], v[2]);
  }
  std::array<int, 3> color(const YAML::Node& map, const char* key, std::array<int, 3> def,
                           const std::string& where) const {
    const YAML::Node n = sub(map, key);
    if (!n.IsDefined() || n.IsNull()) return def;
    const auto v = list(n, where + key, 3, 3);
    for (double c : v)
      if (c < 0 || c > 255) fail(n, where + key, "colour components must be in 0..255");
    return {static_cast<int>(v[0]), static_cast<int>(v[1]), static_cast<int>(v[2])};
  }
  // A vehicle cut-out's name, checked against the table so that a typo names the line.
  std::string vehicle_photo(const YAML::Node& map, const std::string& where) const {
    const std::string name = text(map, "photo", "", where);
    if (name.empty()) return name;
    const auto& names = cutout_names();
    if (name.rfind("car-", 0) != 0 || std::find(names.begin(), names.end(), name) == names.end()) {
      std::string known;
      for (const auto& n : names)
        if (n.rfind("car-", 0) == 0) known += (known.empty() ? "" : ", ") + n;
      fail(map["photo"], where + "photo", "unknown vehicle cut-out '" + name + "' (" + known + ")");
    }
    return name;
  }
  TextureSpec texture(const YAML::Node& map, const char* key, TextureSpec def,
                      const std::string& where, const std::string& assets) const {
    const YAML::Node n = sub(map, key);
    if (!n.IsDefined() || n.IsNull()) return def;
    const std::string w = where + key + ".";
    allow(n, where + key, {"style", "color_a", "color_b", "scale", "contrast", "size", "photo"});
    TextureSpec t = def;
    t.style = text(n, "style", def.style, w);
    t.color_a = color(n, "color_a", def.color_a, w);
    t.color_b = color(n, "color_b", def.color_b, w);
    t.scale = positive(n, "scale", def.scale, w);
    t.contrast = fraction(n, "contrast", def.contrast, w);
    const double size = get(n, "size", def.size, w);
    t.size = static_cast<int>(size);
    if (t.size < 16 || t.size > 4096 || (t.size & (t.size - 1)) != 0)
      fail(n["size"], w + "size", "must be a power of two in 16..4096");
    t.photo = text(n, "photo", def.photo, w);
    if (!t.photo.empty() && t.photo[0] != '/') t.photo = assets + "/" + t.photo;
    if (t.style == "photo" && t.photo.empty())
      fail(n, w + "photo", "style photo needs a photo path");
    return t;
  }

 private:
  std::string file_;
};

}  // namespace

std::string default_assets_dir() {
  if (const char* env = std::getenv("KESTREL_SHARED"); env && *env)
    return std::string(env) + "/data";
  return std::string(KESTREL_SOURCE_DIR) + "/../shared/data";
}

namespace {

Scenario parse_scenario_yaml(const std::string& text, const std::string& name,
                             const ScenarioOverrides& ov) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw Error::at(name, e.mark.line + 1, "", e.msg);
  }
  Reader r(name);
  if (!root.IsMap()) r.fail(root, "", "a scenario file is a YAML mapping");
  if (ov.seed >= 0) root["seed"] = ov.seed;
  if (ov.duration > 0) root["duration"] = ov.duration;
  if (ov.no_movers) root.remove("movers");
  r.allow(root, "",
          {"name", "description", "seed", "duration", "assets", "camera", "imu", "T_body_camera",
           "sensor", "world", "movers", "trajectory"});
  Scenario s;
  s.source = name;
  s.name = r.text(root, "name", name, "");
  const double seed = r.get(root, "seed", 1, "");
  if (seed < 0 || seed != std::floor(seed))
    r.fail(root["seed"], "seed", "must be a non-negative integer");
  s.seed = static_cast<std::uint64_t>(seed);
  s.duration = r.get(root, "duration", -1.0, "");
  s.assets = r.text(root, "assets", default_assets_dir(), "");

  // Sensors and calibration.
  const YAML::Node cam = sub(root, "camera");
  r.allow(cam, "camera", {"width", "height", "fx", "fy", "cx", "cy", "fps"});
  PinholeCamera& c = s.calib.camera;
  c.width = r.whole(cam, "width", 640, 1, 8192, "camera.");
  c.height = r.whole(cam, "height", 480, 1, 8192, "camera.");
  c.fx = r.positive(cam, "fx", 525.0, "camera.");
  c.fy = r.positive(cam, "fy", 525.0, "camera.");
  c.cx = r.get(cam, "cx", (c.width - 1) / 2.0, "camera.");
  c.cy = r.get(cam, "cy", (c.height - 1) / 2.0, "camera.");
  s.calib.fps = r.positive(cam, "fps", 30.0, "camera.");
  const YAML::Node imu = sub(root, "imu");
  r.allow(imu, "imu", {"rate_hz", "gyro_noise", "acc_noise", "gyro_walk", "acc_walk"});
  s.calib.has_imu = true;
  s.calib.imu.rate_hz = r.positive(imu, "rate_hz", 200.0, "imu.");
  s.calib.imu.gyro_noise = r.get(imu, "gyro_noise", s.calib.imu.gyro_noise, "imu.");
  s.calib.imu.acc_noise = r.get(imu, "acc_noise", s.calib.imu.acc_noise, "imu.");
  s.calib.imu.gyro_walk = r.get(imu, "gyro_walk", s.calib.imu.gyro_walk, "imu.");
  s.calib.imu.acc_walk = r.get(imu, "acc_walk", s.calib.imu.acc_walk, "imu.");
  const YAML::Node tbc = sub(root, "T_body_camera");
  r.allow(tbc, "T_body_camera", {"translation", "tilt_deg"});
  {
    // Body (IMU) axes are x forward, y left, z up; the camera (x right, y down, z forward)
    // looks along body x, tilted down by tilt_deg.
    Mat3 R0;
    R0 << 0, 0, 1, -1, 0, 0, 0, -1, 0;
    const double tilt = r.get(tbc, "tilt_deg", 0.0, "T_body_camera.") * kDeg;
    const Mat3 R = Eigen::AngleAxisd(tilt, Vec3::UnitY()).toRotationMatrix() * R0;
    s.calib.T_body_camera =
        SE3(SO3(R), r.vec3(tbc, "translation", Vec3(0.05, 0.0, 0.02), "T_body_camera."));
  }
  s.calib.depth_scale = 5000.0;

  const YAML::Node sen = sub(root, "sensor");
  r.allow(sen, "sensor",
          {"noise", "rgb_noise", "depth_sigma_z2", "depth_min", "depth_max", "edge_holes",
           "motion_blur", "exposure_time", "jitter", "drop_rate", "exposure"});
  SensorSpec& ss = s.sensor;
  ss.noise = r.flag(sen, "noise", true, "sensor.");
  ss.rgb_noise = r.get(sen, "rgb_noise", ss.rgb_noise, "sensor.");
  ss.depth_sigma_z2 = r.get(sen, "depth_sigma_z2", ss.depth_sigma_z2, "sensor.");
  ss.depth_min = r.get(sen, "depth_min", ss.depth_min, "sensor.");
  ss.depth_max = r.positive(sen, "depth_max", ss.depth_max, "sensor.");
  if (ss.depth_max > 13.0)
    r.fail(sen["depth_max"], "sensor.depth_max", "16-bit depth at 5000 per metre ends at 13.1 m");
  ss.edge_holes = r.fraction(sen, "edge_holes", ss.edge_holes, "sensor.");
  // The sequence's calibration says the sensor's range, so the maps trust its depth as far as
  // it reaches (calib.yaml: depth_max).
  s.calib.depth_max = ss.depth_max;
  ss.motion_blur = r.whole(sen, "motion_blur", 0, 0, 64, "sensor.");
  ss.exposure_time = r.get(sen, "exposure_time", ss.exposure_time, "sensor.");
  ss.jitter = r.get(sen, "jitter", 0.0, "sensor.");
  ss.drop_rate = r.fraction(sen, "drop_rate", 0.0, "sensor.");
  if (!sub(sen, "exposure").IsNull()) {
    const YAML::Node e = sub(sen, "exposure");
    if (!e.IsSequence()) r.fail(e, "sensor.exposure", "expected a list of [t, gain]");
    for (std::size_t i = 0; i < e.size(); ++i) {
      const auto v = r.list(e[i], "sensor.exposure[" + std::to_string(i) + "]", 2, 2);
      if (!(v[1] > 0))
        r.fail(e[i], "sensor.exposure[" + std::to_string(i) + "]", "gain must be > 0");
      ss.exposure.push_back({v[0], v[1]});
    }
  }

  // The world.
  const YAML::Node world = sub(root, "world");
  r.allow(world, "world",
          {"sky_top", "sky_bottom", "ground", "boxes", "rooms", "objects", "lights"});
  s.sky_top = r.color(world, "sky_top", s.sky_top, "world.");
  s.sky_bottom = r.color(world, "sky_bottom", s.sky_bottom, "world.");
  if (!sub(world, "ground").IsNull()) {
    const YAML::Node g = sub(world, "ground");
    r.allow(g, "world.ground", {"center", "size", "texture", "shuffle"});
    s.has_ground = true;
    s.ground_center = r.vec3(g, "center", Vec3::Zero(), "world.ground.");
    if (!sub(g, "size").IsNull()) {
      const auto v = r.list(sub(g, "size"), "world.ground.size", 2, 2);
      s.ground_size = {v[0], v[1]};
    }
    s.ground_texture = r.texture(g, "texture", TextureSpec{}, "world.ground.", s.assets);
    s.ground_shuffle = r.flag(g, "shuffle", false, "world.ground.");
  }
  for (const char* key : {"boxes", "rooms"}) {
    const YAML::Node list = sub(world, key);
    if (list.IsNull()) continue;
    if (!list.IsSequence()) r.fail(list, std::string("world.") + key, "expected a list");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string w = std::string("world.") + key + "[" + std::to_string(i) + "].";
      r.allow(list[i], w, {"center", "size", "yaw_deg", "texture"});
      StaticBoxSpec b;
      b.inward = std::string(key) == "rooms";
      b.center = r.vec3(list[i], "center", Vec3::Zero(), w);
      b.size = r.vec3(list[i], "size", Vec3::Ones(), w);
      b.yaw = r.get(list[i], "yaw_deg", 0.0, w) * kDeg;
      b.texture = r.texture(list[i], "texture", TextureSpec{}, w, s.assets);
      s.boxes.push_back(b);
    }
  }
  if (const YAML::Node list = sub(world, "objects"); !list.IsNull()) {
    if (!list.IsSequence()) r.fail(list, "world.objects", "expected a list");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string w = "world.objects[" + std::to_string(i) + "].";
      r.allow(list[i], w, {"label", "center", "size", "yaw_deg", "texture", "photo"});
      ObjectSpec o;
      o.label = r.text(list[i], "label", "", w);
      if (o.label.empty())
        r.fail(list[i], w + "label", "an object needs a label (a COCO class name)");
      o.size = r.vec3(list[i], "size", Vec3(0.5, 0.5, 0.9), w);
      // The centre may omit z: the object then stands on the floor.
      const Vec3 c3 = r.vec3(list[i], "center", Vec3(0, 0, -1e9), w);
      o.center = Vec3(c3.x(), c3.y(), c3.z() < -1e8 ? 0.5 * o.size.z() : c3.z());
      o.yaw = r.get(list[i], "yaw_deg", 0.0, w) * kDeg;
      TextureSpec wood;
      wood.style = "wood";
      wood.color_a = {150, 105, 65};
      wood.color_b = {95, 62, 38};
      wood.scale = 1.0;
      o.texture = r.texture(list[i], "texture", wood, w, s.assets);
      o.photo = r.vehicle_photo(list[i], w);
      s.objects.push_back(o);
    }
  }
  if (const YAML::Node list = sub(world, "lights"); !list.IsNull()) {
    if (!list.IsSequence()) r.fail(list, "world.lights", "expected a list");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string w = "world.lights[" + std::to_string(i) + "].";
      r.allow(list[i], w, {"min", "max", "gain"});
      s.lights.push_back({r.vec3(list[i], "min", Vec3::Zero(), w),
                          r.vec3(list[i], "max", Vec3::Zero(), w),
                          r.positive(list[i], "gain", 0.3, w)});
    }
  }

  // Movers.
  if (const YAML::Node list = root["movers"]; list.IsDefined() && !list.IsNull()) {
    if (!list.IsSequence()) r.fail(list, "movers", "expected a list");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string w = "movers[" + std::to_string(i) + "].";
      const YAML::Node m = list[i];
      r.allow(m, w,
              {"type", "label", "sprite", "photo", "path", "speed", "start", "stop", "mode",
               "height", "size", "center", "yaw_deg", "rate_deg", "flap_hz", "texture"});
      MoverSpec mv;
      mv.type = r.text(m, "type", "person", w);
      if (mv.type != "person" && mv.type != "vehicle" && mv.type != "box" && mv.type != "chair" &&
          mv.type != "spin" && mv.type != "bird") {
        r.fail(m["type"], w + "type",
               "unknown mover type '" + mv.type + "' (person, vehicle, box, chair, spin, bird)");
      }
      const std::string default_label = mv.type == "person"    ? "person"
                                        : mv.type == "vehicle" ? "car"
                                        : mv.type == "box"     ? "box"
                                        : mv.type == "bird"    ? "bird"
                                                               : "chair";
      mv.label = r.text(m, "label", default_label, w);
      mv.sprite = r.whole(m, "sprite", 0, 0, 1000, w);
      mv.photo = r.vehicle_photo(m, w);
      if (!mv.photo.empty() && mv.type != "vehicle")
        r.fail(m["photo"], w + "photo", "only a vehicle carries a photo");
      mv.flap_hz = r.positive(m, "flap_hz", mv.flap_hz, w);
      mv.speed = r.get(m, "speed", mv.speed, w);
      mv.start = r.get(m, "start", 0.0, w);
      mv.stop = r.get(m, "stop", -1.0, w);
      mv.mode = r.text(m, "mode", "loop", w);
      if (mv.mode != "loop" && mv.mode != "pingpong" && mv.mode != "once")
        r.fail(m["mode"], w + "mode", "loop, pingpong or once");
      mv.height = r.positive(m, "height", 1.75, w);
      const Vec3 def_size = mv.type == "vehicle"                      ? Vec3(4.2, 1.8, 1.5)
                            : mv.type == "chair" || mv.type == "spin" ? Vec3(0.5, 0.5, 0.95)
                            : mv.type == "bird"                       ? Vec3(0.35, 0.8, 0.12)
                                                                      : Vec3(0.5, 0.5, 0.5);
      mv.size = r.vec3(m, "size", def_size, w);
      mv.center = r.vec3(m, "center", Vec3::Zero(), w);
      mv.yaw = r.get(m, "yaw_deg", 0.0, w) * kDeg;
      mv.rate = r.get(m, "rate_deg", 90.0, w) * kDeg;
      TextureSpec def_tex;
      def_tex.style = mv.type == "vehicle" ? "car" : mv.type == "box" ? "posters" : "wood";
      if (def_tex.style == "wood") def_tex.color_a = {150, 105, 65}, def_tex.color_b = {95, 62, 38};
      if (mv.type == "vehicle") def_tex.color_a = {170, 30, 30};
      if (mv.type == "bird") {  // a pigeon's grey with darker bars
        def_tex = TextureSpec{"noise", {120, 122, 130}, {55, 55, 62}, 0.3, 1.0, 64, ""};
      }
      mv.texture = r.texture(m, "texture", def_tex, w, s.assets);
      if (m["path"].IsDefined()) {
        const YAML::Node p = m["path"];
        if (!p.IsSequence() || p.size() == 0)
          r.fail(p, w + "path", "expected a list of [x, y] or [x, y, z]");
        for (std::size_t k = 0; k < p.size(); ++k) {
          const auto v = r.list(p[k], w + "path[" + std::to_string(k) + "]", 2, 3);
          mv.path.emplace_back(v[0], v[1], v.size() > 2 ? v[2] : 0.0);
        }
      } else if (mv.type != "spin") {
        r.fail(m, w + "path", "this mover needs a path");
      }
      s.movers.push_back(mv);
    }
  }

  // Trajectory.
  const YAML::Node tr = root["trajectory"];
  if (!tr.IsDefined()) r.fail(root, "trajectory", "missing");
  r.allow(tr, "trajectory", {"kind", "segment_time", "laps", "waypoints", "wobble"});
  TrajectorySpec& ts = s.trajectory;
  ts.kind = r.text(tr, "kind", "handheld", "trajectory.");
  if (ts.kind != "handheld" && ts.kind != "ugv" && ts.kind != "uav")
    r.fail(tr["kind"], "trajectory.kind", "handheld, ugv or uav");
  ts.segment_time = r.positive(tr, "segment_time", 1.0, "trajectory.");
  ts.laps = r.whole(tr, "laps", 1, 1, 1000, "trajectory.");
  const YAML::Node wp = tr["waypoints"];
  if (!wp.IsSequence() || wp.size() == 0)
    r.fail(wp.IsDefined() ? wp : tr, "trajectory.waypoints",
           "expected a list of [x, y, z, yaw_deg(, pitch_deg, roll_deg)]");
  for (std::size_t k = 0; k < wp.size(); ++k) {
    const auto v = r.list(wp[k], "trajectory.waypoints[" + std::to_string(k) + "]", 4, 6);
    TrajectoryKnot kn;
    kn.position = Vec3(v[0], v[1], v[2]);
    kn.yaw = v[3] * kDeg;
    if (v.size() > 4) kn.pitch = v[4] * kDeg;
    if (v.size() > 5) kn.roll = v[5] * kDeg;
    if (ts.kind == "ugv") kn.pitch = kn.roll = 0.0;  // planar: the floor keeps it level
    ts.knots.push_back(kn);
  }
  const YAML::Node wob = sub(tr, "wobble");
  r.allow(wob, "trajectory.wobble", {"position", "rotation_deg", "frequency", "fade_heights"});
  const double def_pos = ts.kind == "handheld" ? 0.02 : ts.kind == "uav" ? 0.05 : 0.0;
  const double def_rot = ts.kind == "handheld" ? 2.0 : ts.kind == "uav" ? 1.5 : 0.0;
  ts.wobble_position = r.get(wob, "position", def_pos, "trajectory.wobble.");
  ts.wobble_rotation = r.get(wob, "rotation_deg", def_rot, "trajectory.wobble.") * kDeg;
  ts.wobble_frequency = r.positive(wob, "frequency", 0.8, "trajectory.wobble.");
  if (wob["fade_heights"].IsDefined()) {
    const auto h = r.list(wob["fade_heights"], "trajectory.wobble.fade_heights", 2, 2);
    if (!(h[1] > h[0]))
      r.fail(wob["fade_heights"], "trajectory.wobble.fade_heights",
             "expected [still_below_z, full_from_z] with the second above the first");
    ts.wobble_fade_still = h[0];
    ts.wobble_fade_full = h[1];
  }

  s.yaml = YAML::Dump(root) + "\n";
  return s;
}

}  // namespace

Scenario parse_scenario(const std::string& text, const std::string& name,
                        const ScenarioOverrides& ov) {
  try {
    return parse_scenario_yaml(text, name, ov);
  } catch (const YAML::Exception& e) {
    // A node of the wrong kind (a list where a map belongs, say) surfaces from yaml-cpp itself;
    // its mark still names the line.
    throw Error::at(name, e.mark.is_null() ? 0 : e.mark.line + 1, "", e.msg);
  }
}

Scenario load_scenario(const std::string& name_or_path, const ScenarioOverrides& overrides) {
  if (const char* text = builtin_scenario(name_or_path)) {
    return parse_scenario(text, "builtin:" + name_or_path, overrides);
  }
  std::ifstream in(name_or_path);
  if (!in) {
    std::string names;
    for (const auto& n : builtin_scenario_names()) names += (names.empty() ? "" : ", ") + n;
    throw Error::at(name_or_path, 0, "scenario",
                    "no such file and no built-in of that name (built-ins: " + names + ")");
  }
  std::stringstream buf;
  buf << in.rdbuf();
  return parse_scenario(buf.str(), name_or_path, overrides);
}

}  // namespace kestrel::sim
