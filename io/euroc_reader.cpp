#include "io/euroc_reader.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unordered_map>

#include "core/config.hpp"
#include "core/error.hpp"
#include "io/image_io.hpp"
#include "io/trajectory_io.hpp"
#include "io/yaml_fields.hpp"

namespace kestrel::io {
namespace fs = std::filesystem;

namespace {

constexpr int kMaxImageSide = 65536;

PinholeCamera kalibr_camera(const YamlFile& y, const YAML::Node& n, const std::string& f) {
  PinholeCamera c;
  const auto in = y.numbers(y.require(n, "intrinsics", f + ".intrinsics"), f + ".intrinsics");
  if (in.size() != 4) y.fail(n["intrinsics"], f + ".intrinsics", "expected [fu, fv, pu, pv]");
  c.fx = in[0], c.fy = in[1], c.cx = in[2], c.cy = in[3];
  const YAML::Node res_node = y.require(n, "resolution", f + ".resolution");
  const auto res = y.numbers(res_node, f + ".resolution");
  if (res.size() != 2) y.fail(res_node, f + ".resolution", "expected [width, height]");
  c.width = y.whole(res[0], res_node, f + ".resolution", 1, kMaxImageSide);
  c.height = y.whole(res[1], res_node, f + ".resolution", 1, kMaxImageSide);
  if (n["camera_model"] && y.text(n["camera_model"], f + ".camera_model") != "pinhole") {
    y.fail(n["camera_model"], f + ".camera_model", "only the pinhole camera model is supported");
  }
  const std::string model = n["distortion_model"]
                                ? y.text(n["distortion_model"], f + ".distortion_model")
                                : std::string("none");
  const auto m = distortion_model_from_string(model);
  if (!m) y.fail(n["distortion_model"], f + ".distortion_model", "unknown model '" + model + "'");
  c.model = *m;
  if (n["distortion_coeffs"]) {
    const auto d = y.numbers(n["distortion_coeffs"], f + ".distortion_coeffs");
    const std::size_t most = c.model == DistortionModel::kEquidistant ? 4 : 5;
    if (d.size() > most || (c.model != DistortionModel::kNone && d.size() < 4)) {
      y.fail(n["distortion_coeffs"], f + ".distortion_coeffs",
             "expected 4 or 5 coefficients for " + to_string(c.model));
    }
    for (std::size_t i = 0; i < d.size(); ++i) c.dist[i] = d[i];
  }
  return c;
}

bool yaml_has_key(const std::string& path, const std::string& key) {
  if (!fs::is_regular_file(path)) return false;
  const YamlFile y = YamlFile::read(path);
  return y.root().IsMap() && y.root()[key].IsDefined();
}

std::string find_root(const std::string& dir) {
  if (fs::is_regular_file(fs::path(dir) / "mav0" / "cam0" / "data.csv")) {
    return (fs::path(dir) / "mav0").string();
  }
  if (fs::is_regular_file(fs::path(dir) / "cam0" / "data.csv")) return dir;
  throw Error::at(dir, 0, "", "not an ASL dataset: no mav0/cam0/data.csv");
}

}  // namespace

void load_kalibr_camchain(const std::string& path, Calibration* calib) {
  const YamlFile y = YamlFile::read(path);
  const YAML::Node& root = y.root();
  const YAML::Node cam0 = y.require(root, "cam0", "cam0");
  calib->camera = kalibr_camera(y, cam0, "cam0");
  const SE3 T_c0_imu =
      y.transform(y.require(cam0, "T_cam_imu", "cam0.T_cam_imu"), "cam0.T_cam_imu");
  calib->T_body_camera = T_c0_imu.inverse();
  calib->right.reset();
  if (root.IsMap() && root["cam1"]) {
    const YAML::Node cam1 = root["cam1"];
    calib->right = kalibr_camera(y, cam1, "cam1");
    const SE3 T_c1_imu =
        y.transform(y.require(cam1, "T_cam_imu", "cam1.T_cam_imu"), "cam1.T_cam_imu");
    calib->T_left_right = T_c0_imu * T_c1_imu.inverse();
  }
}

EurocReader::EurocReader(const std::string& dir, const EurocOptions& options) {
  const std::string root = find_root(dir);
  const fs::path r(root);
  const std::string cam0_yaml = (r / "cam0" / "sensor.yaml").string();
  const std::string cam1_yaml = (r / "cam1" / "sensor.yaml").string();
  const std::string imu_yaml = (r / "imu0" / "sensor.yaml").string();
  const std::string imu_csv = (r / "imu0" / "data.csv").string();
  const std::string camchain = (r.parent_path() / "dso" / "camchain.yaml").string();

  // Calibration.
  std::string calib_from;
  bool imu_from_config = false;
  if (!options.config_file.empty()) {
    if (yaml_has_key(options.config_file, "cam0")) {
      load_kalibr_camchain(options.config_file, &calib_);
    } else {
      calib_ = load_config(options.config_file).calib;
      imu_from_config = calib_.has_imu;
    }
    calib_from = options.config_file;
  } else if (!yaml_has_key(cam0_yaml, "intrinsics") && fs::is_regular_file(camchain)) {
    load_kalibr_camchain(camchain, &calib_);
    calib_from = camchain;
  } else {
    const Config cfg = load_config(cam0_yaml);
    calib_.camera = cfg.calib.camera;
    calib_.fps = cfg.calib.fps;
    const SE3 T_B_c0 = cfg.calib.T_body_camera;
    SE3 T_B_imu;
    if (fs::is_regular_file(imu_yaml)) {
      const YamlFile y = YamlFile::read(imu_yaml);
      if (y.root().IsMap() && y.root()["T_BS"]) T_B_imu = y.transform(y.root()["T_BS"], "T_BS");
    }
    calib_.T_body_camera = T_B_imu.inverse() * T_B_c0;
    if (options.stereo && fs::is_regular_file(cam1_yaml)) {
      SE3 T_B_c1;
      calib_.right = load_euroc_camera(cam1_yaml, &T_B_c1);
      calib_.T_left_right = T_B_c0.inverse() * T_B_c1;
    }
    calib_from = "sensor.yaml files";
  }
  if (!options.stereo) calib_.right.reset();
  if (!imu_from_config && fs::is_regular_file(imu_yaml)) {
    calib_.imu = load_euroc_imu(imu_yaml);
  }

  // Image lists: stereo pairs by equal stamps.
  left_csv_ = (r / "cam0" / "data.csv").string();
  const std::vector<ListEntry> left = parse_asl_image_csv(TextTable::read(left_csv_));
  const bool stereo = calib_.right.has_value() && fs::is_regular_file(r / "cam1" / "data.csv");
  if (!stereo) calib_.right.reset();
  std::unordered_map<Timestamp, const ListEntry*> right_by_stamp;
  std::vector<ListEntry> right;
  if (stereo) {
    right_csv_ = (r / "cam1" / "data.csv").string();
    right = parse_asl_image_csv(TextTable::read(right_csv_));
    for (const ListEntry& e : right) right_by_stamp.emplace(e.t, &e);
  }
  std::vector<Timestamp> stamps;
  for (const ListEntry& e : left) {
    Pair p;
    p.t = e.t;
    p.left = (r / "cam0" / "data" / e.path).string();
    p.left_line = e.line;
    if (stereo) {
      const auto it = right_by_stamp.find(e.t);
      if (it == right_by_stamp.end()) {
        ++unmatched_left_;
        continue;
      }
      p.right = (r / "cam1" / "data" / it->second->path).string();
      p.right_line = it->second->line;
    }
    stamps.push_back(p.t);
    frames_.push_back(std::move(p));
  }
  if (stereo) unmatched_right_ = right.size() - frames_.size();

  std::vector<ImuSample> imu;
  if (fs::is_regular_file(imu_csv)) {
    imu = parse_asl_imu_csv(TextTable::read(imu_csv));
    calib_.has_imu = true;
  }
  const std::size_t imu_n = imu.size();
  set_streams(std::move(stamps), std::move(imu));

  std::string gt_from;
  for (const char* gt : {"state_groundtruth_estimate0", "mocap0"}) {
    const fs::path p = r / gt / "data.csv";
    if (fs::is_regular_file(p)) {
      ground_truth_ = read_trajectory(p.string());
      gt_from = std::string(gt) + "/data.csv";
      break;
    }
  }

  std::ostringstream d;
  d << options.name << ":" << dir << " (" << (stereo ? "stereo, " : "monocular, ") << frames_.size()
    << (stereo ? " pairs" : " frames");
  if (unmatched_left_ + unmatched_right_ > 0) {
    d << "; unmatched rows: " << unmatched_left_ << " cam0, " << unmatched_right_ << " cam1";
  }
  d << "; " << imu_n << " IMU samples; " << to_string(calib_.camera.model)
    << " distortion; calibration from " << calib_from << "; "
    << (ground_truth_ ? "ground truth from " + gt_from : std::string("no ground truth")) << ")";
  description_ = d.str();
}

Measurement EurocReader::load_frame(std::size_t index) const {
  const Pair& p = frames_.at(index);
  Image left, right;
  try {
    left = load_image(p.left, ImageKind::kGrey);
  } catch (const Error& e) {
    throw Error::at(left_csv_, p.left_line, "filename", e.what());
  }
  if (p.right.empty()) {
    RgbdFrame f;
    f.t = p.t;
    f.color = std::move(left);
    f.source = p.left;
    f.depth_scale = calib_.depth_scale;
    return f;
  }
  try {
    right = load_image(p.right, ImageKind::kGrey);
  } catch (const Error& e) {
    throw Error::at(right_csv_, p.right_line, "filename", e.what());
  }
  StereoFrame f;
  f.t = p.t;
  f.left = std::move(left);
  f.right = std::move(right);
  f.source = p.left;
  return f;
}

std::unique_ptr<EurocReader> open_euroc(const std::string& dir, const EurocOptions& options) {
  return std::make_unique<EurocReader>(dir, options);
}

}  // namespace kestrel::io
