#include "core/config.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

#include "core/error.hpp"

namespace kestrel {
namespace {

// OpenCV FileStorage writes "%YAML:1.0", which is not a valid YAML directive; yaml-cpp
// rejects it. Blank the line so line numbers in errors still match the user's file.
std::string strip_opencv_header(std::string text) {
  if (text.rfind("%YAML:", 0) == 0) {
    const auto eol = text.find('\n');
    text.replace(0, eol == std::string::npos ? text.size() : eol, "");
  }
  return text;
}

struct Reader {
  std::string file;

  [[noreturn]] void fail(const YAML::Node& node, const std::string& field,
                         const std::string& msg) const {
    const int line = node.IsDefined() ? node.Mark().line + 1 : 0;
    throw Error::at(file, line, field, msg);
  }

  double number(const YAML::Node& node, const std::string& field) const {
    if (!node.IsScalar()) fail(node, field, "expected a number");
    double v = 0.0;
    try {
      v = node.as<double>();
    } catch (const YAML::Exception&) {
      fail(node, field, "expected a number, got '" + node.Scalar() + "'");
    }
    if (!std::isfinite(v)) fail(node, field, "must be finite, got '" + node.Scalar() + "'");
    return v;
  }
  double positive(const YAML::Node& node, const std::string& field) const {
    const double v = number(node, field);
    if (!(v > 0.0)) fail(node, field, "must be positive, got " + node.Scalar());
    return v;
  }
  int integer(const YAML::Node& node, const std::string& field) const {
    const double v = number(node, field);
    if (v != std::floor(v) || v < 0 || v > 1e6) fail(node, field, "expected a size in pixels");
    return static_cast<int>(v);
  }
  std::vector<double> numbers(const YAML::Node& node, const std::string& field) const {
    if (!node.IsSequence()) fail(node, field, "expected a list of numbers");
    std::vector<double> out;
    for (std::size_t i = 0; i < node.size(); ++i) {
      out.push_back(number(node[i], field + "[" + std::to_string(i) + "]"));
    }
    return out;
  }
  // A 4x4 transform given as 16 numbers, or as {rows, cols, data} (EuRoC and OpenCV).
  SE3 transform(const YAML::Node& node, const std::string& field) const {
    YAML::Node data = node;
    if (node.IsMap()) {
      if (!node["data"]) fail(node, field, "matrix has no 'data'");
      data = node["data"];
      if (node["rows"] && integer(node["rows"], field + ".rows") != 4) {
        fail(node["rows"], field + ".rows", "expected 4 rows");
      }
    }
    const std::vector<double> v = numbers(data, field);
    if (v.size() != 16 && v.size() != 12) {
      fail(data, field, "expected 16 numbers (a 4x4 matrix), got " + std::to_string(v.size()));
    }
    Mat4 m = Mat4::Identity();
    for (int r = 0; r < static_cast<int>(v.size()) / 4; ++r) {
      for (int c = 0; c < 4; ++c) m(r, c) = v[r * 4 + c];
    }
    const Mat3 R = m.topLeftCorner<3, 3>();
    if ((R * R.transpose() - Mat3::Identity()).norm() > 1e-3 || R.determinant() < 0.0) {
      fail(data, field, "rotation part is not a rotation matrix");
    }
    return SE3(m);
  }
  const YAML::Node require(const YAML::Node& map, const std::string& key,
                           const std::string& field) const {
    const YAML::Node n = map[key];
    if (!n) fail(map, field, "missing");
    return n;
  }
};

YAML::Node parse_yaml(const std::string& text, const std::string& name) {
  try {
    return YAML::Load(strip_opencv_header(text));
  } catch (const YAML::ParserException& e) {
    throw Error::at(name, e.mark.line + 1, "", "YAML syntax error: " + e.msg);
  }
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error::at(path, 0, "", "cannot open file");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void read_distortion(const Reader& rd, const YAML::Node& list, const std::string& field,
                     PinholeCamera& cam) {
  const std::vector<double> d = rd.numbers(list, field);
  const std::size_t expected_max = cam.model == DistortionModel::kEquidistant ? 4 : 5;
  if (d.size() > expected_max || (cam.model != DistortionModel::kNone && d.size() < 4)) {
    rd.fail(list, field, "expected 4 or 5 coefficients for " + to_string(cam.model));
  }
  for (std::size_t i = 0; i < d.size(); ++i) cam.dist[i] = d[i];
}

PinholeCamera kestrel_camera(const Reader& rd, const YAML::Node& n, const std::string& f) {
  if (!n.IsMap()) rd.fail(n, f, "expected a map");
  PinholeCamera c;
  c.width = rd.integer(rd.require(n, "width", f + ".width"), f + ".width");
  c.height = rd.integer(rd.require(n, "height", f + ".height"), f + ".height");
  c.fx = rd.positive(rd.require(n, "fx", f + ".fx"), f + ".fx");
  c.fy = rd.positive(rd.require(n, "fy", f + ".fy"), f + ".fy");
  c.cx = rd.number(rd.require(n, "cx", f + ".cx"), f + ".cx");
  c.cy = rd.number(rd.require(n, "cy", f + ".cy"), f + ".cy");
  if (n["distortion_model"]) {
    const auto m = distortion_model_from_string(n["distortion_model"].as<std::string>());
    if (!m) rd.fail(n["distortion_model"], f + ".distortion_model", "unknown model");
    c.model = *m;
  }
  if (n["distortion"]) read_distortion(rd, n["distortion"], f + ".distortion", c);
  return c;
}

ImuNoise kestrel_imu(const Reader& rd, const YAML::Node& n) {
  ImuNoise imu;
  if (n["gyro_noise"]) imu.gyro_noise = rd.positive(n["gyro_noise"], "imu.gyro_noise");
  if (n["acc_noise"]) imu.acc_noise = rd.positive(n["acc_noise"], "imu.acc_noise");
  if (n["gyro_walk"]) imu.gyro_walk = rd.positive(n["gyro_walk"], "imu.gyro_walk");
  if (n["acc_walk"]) imu.acc_walk = rd.positive(n["acc_walk"], "imu.acc_walk");
  if (n["rate_hz"]) imu.rate_hz = rd.positive(n["rate_hz"], "imu.rate_hz");
  return imu;
}

Config parse_kestrel(const Reader& rd, const YAML::Node& root) {
  Config cfg;
  Calibration& cal = cfg.calib;
  if (root["camera"]) cal.camera = kestrel_camera(rd, root["camera"], "camera");
  if (root["right_camera"]) {
    cal.right = kestrel_camera(rd, root["right_camera"], "right_camera");
    cal.T_left_right =
        rd.transform(rd.require(root, "T_left_right", "T_left_right"), "T_left_right");
  }
  if (root["T_body_camera"])
    cal.T_body_camera = rd.transform(root["T_body_camera"], "T_body_camera");
  if (root["imu"]) {
    cal.has_imu = true;
    cal.imu = kestrel_imu(rd, root["imu"]);
  }
  if (root["depth_scale"]) cal.depth_scale = rd.positive(root["depth_scale"], "depth_scale");
  if (root["depth_max"]) cal.depth_max = rd.positive(root["depth_max"], "depth_max");
  if (root["fps"]) cal.fps = rd.positive(root["fps"], "fps");
  return cfg;
}

Config parse_orbslam3(const Reader& rd, const YAML::Node& root) {
  Config cfg;
  Calibration& cal = cfg.calib;
  // 1.0 format uses Camera1.*, the older one Camera.*; the type and size live under Camera.*.
  const bool v1 = static_cast<bool>(root["Camera1.fx"]);
  const std::string p = v1 ? "Camera1." : "Camera.";
  auto get = [&](const std::string& key) { return rd.require(root, key, key); };
  auto read_cam = [&](const std::string& pre) {
    PinholeCamera c;
    c.fx = rd.positive(get(pre + "fx"), pre + "fx");
    c.fy = rd.positive(get(pre + "fy"), pre + "fy");
    c.cx = rd.number(get(pre + "cx"), pre + "cx");
    c.cy = rd.number(get(pre + "cy"), pre + "cy");
    const std::string type =
        root["Camera.type"] ? root["Camera.type"].as<std::string>() : "PinHole";
    if (type == "KannalaBrandt8") {
      c.model = DistortionModel::kEquidistant;
      for (int i = 0; i < 4; ++i) {
        const std::string key = pre + "k" + std::to_string(i + 1);
        c.dist[i] = rd.number(get(key), key);
      }
    } else if (type == "PinHole" || type == "Rectified") {
      const char* keys[5] = {"k1", "k2", "p1", "p2", "k3"};
      bool any = false;
      for (int i = 0; i < 5; ++i) {
        if (root[pre + keys[i]]) {
          c.dist[i] = rd.number(root[pre + keys[i]], pre + keys[i]);
          any = any || c.dist[i] != 0.0;
        }
      }
      c.model = any ? DistortionModel::kRadTan : DistortionModel::kNone;
    } else {
      rd.fail(root["Camera.type"], "Camera.type", "unknown camera type '" + type + "'");
    }
    c.width = root["Camera.width"] ? rd.integer(root["Camera.width"], "Camera.width") : 640;
    c.height = root["Camera.height"] ? rd.integer(root["Camera.height"], "Camera.height") : 480;
    return c;
  };
  cal.camera = read_cam(p);
  if (root["Camera.fps"]) cal.fps = rd.positive(root["Camera.fps"], "Camera.fps");
  if (root["Camera2.fx"]) {
    cal.right = read_cam("Camera2.");
    cal.T_left_right = rd.transform(get("Stereo.T_c1_c2"), "Stereo.T_c1_c2");
  } else if (root["Camera.bf"] && !root["DepthMapFactor"] && !root["RGBD.DepthMapFactor"]) {
    // Old-format rectified stereo: the right camera is the left one shifted by the baseline.
    const double bf = rd.positive(root["Camera.bf"], "Camera.bf");
    cal.right = cal.camera;
    cal.T_left_right = SE3(SO3(), Vec3(bf / cal.camera.fx, 0.0, 0.0));
  }
  for (const char* key : {"Tbc", "IMU.T_b_c1"}) {
    if (root[key]) cal.T_body_camera = rd.transform(root[key], key);
  }
  if (root["IMU.NoiseGyro"]) {
    cal.has_imu = true;
    cal.imu.gyro_noise = rd.positive(root["IMU.NoiseGyro"], "IMU.NoiseGyro");
    cal.imu.acc_noise = rd.positive(get("IMU.NoiseAcc"), "IMU.NoiseAcc");
    cal.imu.gyro_walk = rd.positive(get("IMU.GyroWalk"), "IMU.GyroWalk");
    cal.imu.acc_walk = rd.positive(get("IMU.AccWalk"), "IMU.AccWalk");
    cal.imu.rate_hz = rd.positive(get("IMU.Frequency"), "IMU.Frequency");
  }
  for (const char* key : {"DepthMapFactor", "RGBD.DepthMapFactor"}) {
    if (root[key]) cal.depth_scale = rd.positive(root[key], key);
  }
  return cfg;
}

PinholeCamera parse_euroc_camera(const Reader& rd, const YAML::Node& root, SE3* T_bc) {
  PinholeCamera c;
  const std::vector<double> in =
      rd.numbers(rd.require(root, "intrinsics", "intrinsics"), "intrinsics");
  if (in.size() != 4) rd.fail(root["intrinsics"], "intrinsics", "expected [fu, fv, cu, cv]");
  c.fx = in[0];
  c.fy = in[1];
  c.cx = in[2];
  c.cy = in[3];
  const std::vector<double> res =
      rd.numbers(rd.require(root, "resolution", "resolution"), "resolution");
  if (res.size() != 2) rd.fail(root["resolution"], "resolution", "expected [width, height]");
  for (const double v : res) {
    if (!(v >= 1 && v <= 100000) || v != std::floor(v))
      rd.fail(root["resolution"], "resolution", "width and height must be positive integers");
  }
  if (!(c.fx > 0) || !(c.fy > 0))
    rd.fail(root["intrinsics"], "intrinsics", "focal lengths fu, fv must be positive");
  c.width = static_cast<int>(res[0]);
  c.height = static_cast<int>(res[1]);
  const std::string model =
      root["distortion_model"] ? root["distortion_model"].as<std::string>() : "none";
  const auto m = distortion_model_from_string(model);
  if (!m) rd.fail(root["distortion_model"], "distortion_model", "unknown model '" + model + "'");
  c.model = *m;
  if (root["distortion_coefficients"]) {
    read_distortion(rd, root["distortion_coefficients"], "distortion_coefficients", c);
  }
  if (T_bc && root["T_BS"]) *T_bc = rd.transform(root["T_BS"], "T_BS");
  return c;
}

ImuNoise parse_euroc_imu(const Reader& rd, const YAML::Node& root) {
  ImuNoise imu;
  imu.gyro_noise =
      rd.positive(rd.require(root, "gyroscope_noise_density", "gyroscope_noise_density"),
                  "gyroscope_noise_density");
  imu.gyro_walk = rd.positive(rd.require(root, "gyroscope_random_walk", "gyroscope_random_walk"),
                              "gyroscope_random_walk");
  imu.acc_noise =
      rd.positive(rd.require(root, "accelerometer_noise_density", "accelerometer_noise_density"),
                  "accelerometer_noise_density");
  imu.acc_walk =
      rd.positive(rd.require(root, "accelerometer_random_walk", "accelerometer_random_walk"),
                  "accelerometer_random_walk");
  if (root["rate_hz"]) imu.rate_hz = rd.positive(root["rate_hz"], "rate_hz");
  return imu;
}

}  // namespace

namespace {

ConfigDialect detect_dialect_yaml(const std::string& text, const std::string& name) {
  const YAML::Node root = parse_yaml(text, name);
  if (!root.IsMap()) throw Error::at(name, 1, "", "expected a YAML map at the top level");
  if (root["Camera.fx"] || root["Camera1.fx"]) return ConfigDialect::kOrbSlam3;
  if (root["intrinsics"] && root["T_BS"]) return ConfigDialect::kEurocCamera;
  if (root["gyroscope_noise_density"]) return ConfigDialect::kEurocImu;
  return ConfigDialect::kKestrel;
}

Config parse_config_yaml(const std::string& text, const std::string& name) {
  const YAML::Node root = parse_yaml(text, name);
  if (root.IsNull()) return Config{Calibration{}, name};
  if (!root.IsMap()) throw Error::at(name, 1, "", "expected a YAML map at the top level");
  const Reader rd{name};
  Config cfg;
  switch (detect_dialect_yaml(text, name)) {
    case ConfigDialect::kOrbSlam3:
      cfg = parse_orbslam3(rd, root);
      break;
    case ConfigDialect::kEurocCamera:
      cfg.calib.camera = parse_euroc_camera(rd, root, &cfg.calib.T_body_camera);
      if (root["rate_hz"]) cfg.calib.fps = rd.positive(root["rate_hz"], "rate_hz");
      break;
    case ConfigDialect::kEurocImu:
      cfg.calib.has_imu = true;
      cfg.calib.imu = parse_euroc_imu(rd, root);
      break;
    case ConfigDialect::kKestrel:
      cfg = parse_kestrel(rd, root);
      break;
  }
  cfg.source = name;
  return cfg;
}

// yaml-cpp throws on a node of the wrong kind (indexing a list as a map, say) from deep inside
// the readers; its mark still names the line, so it becomes an error that names the file.
template <typename F>
auto with_yaml_errors(const std::string& name, F&& f) {
  try {
    return f();
  } catch (const YAML::Exception& e) {
    throw Error::at(name, e.mark.is_null() ? 0 : e.mark.line + 1, "", e.msg);
  }
}

}  // namespace

ConfigDialect detect_dialect(const std::string& text, const std::string& name) {
  return with_yaml_errors(name, [&] { return detect_dialect_yaml(text, name); });
}

Config parse_config(const std::string& text, const std::string& name) {
  return with_yaml_errors(name, [&] { return parse_config_yaml(text, name); });
}

Config load_config(const std::string& path) { return parse_config(read_text(path), path); }

PinholeCamera load_euroc_camera(const std::string& path, SE3* T_body_camera) {
  return with_yaml_errors(path, [&] {
    const YAML::Node root = parse_yaml(read_text(path), path);
    return parse_euroc_camera(Reader{path}, root, T_body_camera);
  });
}

ImuNoise load_euroc_imu(const std::string& path) {
  return with_yaml_errors(path, [&] {
    const YAML::Node root = parse_yaml(read_text(path), path);
    return parse_euroc_imu(Reader{path}, root);
  });
}

std::string to_yaml(const Calibration& c) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  auto camera = [&](const char* key, const PinholeCamera& cam) {
    out << YAML::Key << key << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "width" << YAML::Value << cam.width;
    out << YAML::Key << "height" << YAML::Value << cam.height;
    out << YAML::Key << "fx" << YAML::Value << cam.fx << YAML::Key << "fy" << YAML::Value << cam.fy;
    out << YAML::Key << "cx" << YAML::Value << cam.cx << YAML::Key << "cy" << YAML::Value << cam.cy;
    out << YAML::Key << "distortion_model" << YAML::Value << to_string(cam.model);
    out << YAML::Key << "distortion" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    const int n = cam.model == DistortionModel::kEquidistant ? 4 : 5;
    for (int i = 0; i < n; ++i) out << cam.dist[i];
    out << YAML::EndSeq << YAML::EndMap;
  };
  auto transform = [&](const char* key, const SE3& T) {
    out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq;
    const Mat4 m = T.matrix();
    for (int r = 0; r < 4; ++r) {
      for (int col = 0; col < 4; ++col) out << m(r, col);
    }
    out << YAML::EndSeq;
  };
  out << YAML::BeginMap;
  camera("camera", c.camera);
  if (c.right) {
    camera("right_camera", *c.right);
    transform("T_left_right", c.T_left_right);
  }
  transform("T_body_camera", c.T_body_camera);
  if (c.has_imu) {
    out << YAML::Key << "imu" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "gyro_noise" << YAML::Value << c.imu.gyro_noise;
    out << YAML::Key << "acc_noise" << YAML::Value << c.imu.acc_noise;
    out << YAML::Key << "gyro_walk" << YAML::Value << c.imu.gyro_walk;
    out << YAML::Key << "acc_walk" << YAML::Value << c.imu.acc_walk;
    out << YAML::Key << "rate_hz" << YAML::Value << c.imu.rate_hz;
    out << YAML::EndMap;
  }
  out << YAML::Key << "depth_scale" << YAML::Value << c.depth_scale;
  if (c.depth_max) out << YAML::Key << "depth_max" << YAML::Value << *c.depth_max;
  out << YAML::Key << "fps" << YAML::Value << c.fps;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace kestrel
