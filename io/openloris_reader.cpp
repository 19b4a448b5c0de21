#include "io/openloris_reader.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "core/config.hpp"
#include "core/error.hpp"
#include "io/trajectory_io.hpp"
#include "io/yaml_fields.hpp"

namespace kestrel::io {
namespace fs = std::filesystem;

std::vector<ImuSample> merge_accel_gyro(const std::vector<StampedVector>& accel,
                                        const std::vector<StampedVector>& gyro) {
  std::vector<ImuSample> out;
  if (accel.empty()) return out;
  std::size_t k = 0;  // accel[k].t <= g.t < accel[k + 1].t
  for (const StampedVector& g : gyro) {
    if (g.t < accel.front().t || g.t > accel.back().t) continue;
    while (k + 1 < accel.size() && accel[k + 1].t <= g.t) ++k;
    ImuSample s;
    s.t = g.t;
    s.gyro = g.v;
    if (k + 1 < accel.size()) {
      const double a =
          static_cast<double>(g.t - accel[k].t) / static_cast<double>(accel[k + 1].t - accel[k].t);
      s.acc = (1.0 - a) * accel[k].v + a * accel[k + 1].v;
    } else {
      s.acc = accel[k].v;
    }
    out.push_back(s);
  }
  return out;
}

namespace {

constexpr int kMaxImageSide = 65536;

PinholeCamera read_camera(const YamlFile& y, const YAML::Node& n, const std::string& f) {
  PinholeCamera c;
  c.width = y.whole(y.require(n, "width", f + ".width"), f + ".width", 1, kMaxImageSide);
  c.height = y.whole(y.require(n, "height", f + ".height"), f + ".height", 1, kMaxImageSide);
  const auto in = y.numbers(y.require(n, "intrinsics", f + ".intrinsics"), f + ".intrinsics");
  if (in.size() != 4) y.fail(n["intrinsics"], f + ".intrinsics", "expected [fx, fy, cx, cy]");
  c.fx = in[0], c.fy = in[1], c.cx = in[2], c.cy = in[3];
  if (!(c.fx > 0 && c.fy > 0))
    y.fail(n["intrinsics"], f + ".intrinsics", "focal lengths must be positive");
  std::vector<double> d;
  if (n["distortion_coefficients"]) {
    d = y.numbers(n["distortion_coefficients"], f + ".distortion_coefficients");
  }
  const bool all_zero = std::all_of(d.begin(), d.end(), [](double v) { return v == 0.0; });
  std::string model =
      n["distortion_model"] ? y.text(n["distortion_model"], f + ".distortion_model") : "";
  std::transform(model.begin(), model.end(), model.begin(),
                 [](unsigned char ch) { return std::tolower(ch); });
  if (all_zero) {
    c.model = DistortionModel::kNone;
  } else if (model.find("kannala") != std::string::npos ||
             model.find("equidistant") != std::string::npos) {
    c.model = DistortionModel::kEquidistant;
  } else if (model.find("brown") != std::string::npos ||
             model.find("radtan") != std::string::npos ||
             model.find("plumb") != std::string::npos ||
             model.find("radial") != std::string::npos) {
    c.model = DistortionModel::kRadTan;
  } else {
    y.fail(n["distortion_model"], f + ".distortion_model",
           "unknown distortion model '" + model + "'");
  }
  const std::size_t most = c.model == DistortionModel::kEquidistant ? 4 : 5;
  if (!all_zero && d.size() > most) {
    y.fail(n["distortion_coefficients"], f + ".distortion_coefficients", "too many coefficients");
  }
  for (std::size_t i = 0; i < d.size() && i < 5; ++i) c.dist[i] = d[i];
  return c;
}

// noise_variances / bias_variances are taken as per-sample (discrete) variances at the
// sensor's rate, converted to the continuous densities Kalibr and ImuNoise use:
// sigma_c = sigma_d / sqrt(rate) for white noise, sigma_c = sigma_d * sqrt(rate) for the walk.
void read_imu_noise(const YamlFile& y, const YAML::Node& n, const std::string& f, bool gyro,
                    ImuNoise* imu) {
  const double rate = n["fps"] ? y.number(n["fps"], f + ".fps") : imu->rate_hz;
  if (!(rate > 0)) y.fail(n["fps"], f + ".fps", "must be positive");
  auto largest = [&](const char* key) {
    const auto v = y.numbers(n[key], f + "." + key);
    double m = 0.0;
    for (double x : v) {
      if (x < 0) y.fail(n[key], f + "." + key, "variances must not be negative");
      m = std::max(m, x);
    }
    return m;
  };
  if (n["noise_variances"]) {
    const double s = std::sqrt(largest("noise_variances")) / std::sqrt(rate);
    if (s > 0) (gyro ? imu->gyro_noise : imu->acc_noise) = s;
  }
  if (n["bias_variances"]) {
    const double s = std::sqrt(largest("bias_variances")) * std::sqrt(rate);
    if (s > 0) (gyro ? imu->gyro_walk : imu->acc_walk) = s;
  }
  if (gyro) imu->rate_hz = rate;
}

// T_base_frame by chaining trans_matrix entries (T_parent_child) up to the root.
std::optional<SE3> pose_in_root(const std::map<std::string, std::pair<std::string, SE3>>& tree,
                                std::string frame) {
  SE3 T;
  for (std::size_t depth = 0; depth <= tree.size(); ++depth) {
    const auto it = tree.find(frame);
    if (it == tree.end()) return depth == 0 ? std::nullopt : std::optional<SE3>(T);
    T = it->second.second * T;
    frame = it->second.first;
  }
  return std::nullopt;  // a cycle
}

}  // namespace

std::unique_ptr<RgbdListSource> open_openloris(const std::string& dir,
                                               const OpenLorisOptions& options) {
  const fs::path d(dir);
  if (!fs::is_directory(d)) throw Error::at(dir, 0, "", "not a directory");
  RgbdListSource::Contents c;

  // Calibration.
  std::string calib_from;
  if (!options.config_file.empty()) {
    c.calib = load_config(options.config_file).calib;
    calib_from = options.config_file;
  } else {
    const std::string sensors = (d / "sensors.yaml").string();
    const YamlFile y = YamlFile::read(sensors);
    c.calib.camera =
        read_camera(y, y.require(y.root(), "d400_color_optical_frame", "d400_color_optical_frame"),
                    "d400_color_optical_frame");
    const YAML::Node color = y.root()["d400_color_optical_frame"];
    if (color["fps"]) c.calib.fps = y.number(color["fps"], "d400_color_optical_frame.fps");
    for (const char* name : {"d400_gyroscope", "d400_accelerometer"}) {
      if (y.root()[name]) {
        read_imu_noise(y, y.root()[name], name, std::string(name) == "d400_gyroscope",
                       &c.calib.imu);
      }
    }
    c.calib.depth_scale = 1000.0;  // RealSense depth in millimetres
    calib_from = "sensors.yaml";
    const std::string trans = (d / "trans_matrix.yaml").string();
    if (fs::is_regular_file(trans)) {
      const YamlFile t = YamlFile::read(trans);
      const YAML::Node list = t.require(t.root(), "trans_matrix", "trans_matrix");
      if (!list.IsSequence()) t.fail(list, "trans_matrix", "expected a list");
      std::map<std::string, std::pair<std::string, SE3>> tree;
      for (std::size_t i = 0; i < list.size(); ++i) {
        const std::string f = "trans_matrix[" + std::to_string(i) + "]";
        const YAML::Node e = list[i];
        const std::string child =
            t.text(t.require(e, "child_frame", f + ".child_frame"), f + ".child_frame");
        const std::string parent =
            t.text(t.require(e, "parent_frame", f + ".parent_frame"), f + ".parent_frame");
        tree[child] = {parent, t.transform(t.require(e, "matrix", f + ".matrix"), f + ".matrix")};
      }
      const auto T_base_color = pose_in_root(tree, "d400_color_optical_frame");
      std::optional<SE3> T_base_imu;
      for (const char* imu : {"d400_imu", "d400_gyroscope", "d400_accelerometer"}) {
        if ((T_base_imu = pose_in_root(tree, imu))) break;
      }
      if (T_base_color && T_base_imu) {
        c.calib.T_body_camera = T_base_imu->inverse() * *T_base_color;
        calib_from += " + trans_matrix.yaml";
      }
    }
  }

  // Frames: colour and aligned depth by nearest stamp.
  const std::string color_list = (d / "color.txt").string();
  const std::string depth_list = (d / "aligned_depth.txt").string();
  const std::vector<ListEntry> color = parse_tum_list(TextTable::read(color_list));
  const std::vector<ListEntry> depth = parse_tum_list(TextTable::read(depth_list));
  std::vector<Timestamp> ta, tb;
  for (const auto& e : color) ta.push_back(e.t);
  for (const auto& e : depth) tb.push_back(e.t);
  for (const auto& [i, j] : associate(ta, tb, from_seconds(options.max_difference))) {
    RgbdEntry r;
    r.t = color[i].t;
    r.color = resolve_path(dir, color[i].path);
    r.color_list = color_list;
    r.color_line = color[i].line;
    r.depth = resolve_path(dir, depth[j].path);
    r.depth_list = depth_list;
    r.depth_line = depth[j].line;
    c.frames.push_back(std::move(r));
  }

  // IMU.
  const fs::path acc_path = d / "d400_accelerometer.txt";
  const fs::path gyro_path = d / "d400_gyroscope.txt";
  if (fs::is_regular_file(acc_path) && fs::is_regular_file(gyro_path)) {
    c.imu =
        merge_accel_gyro(parse_stamped_vectors(TextTable::read(acc_path.string()), "ax ay az"),
                         parse_stamped_vectors(TextTable::read(gyro_path.string()), "gx gy gz"));
    c.calib.has_imu = !c.imu.empty();
  }

  const std::string gt = (d / "groundtruth.txt").string();
  if (fs::is_regular_file(gt) && !TextTable::read(gt).empty()) c.ground_truth = read_trajectory(gt);

  std::ostringstream desc;
  desc << "openloris:" << dir << " (RGB-D, " << c.frames.size() << " frames of " << color.size()
       << " colour / " << depth.size() << " depth; " << c.imu.size()
       << " IMU samples; calibration from " << calib_from << "; "
       << (c.ground_truth ? "ground truth (base_link)" : "no ground truth") << ")";
  c.description = desc.str();
  return std::make_unique<RgbdListSource>(std::move(c));
}

}  // namespace kestrel::io
