#include "io/tum_rgbd_reader.hpp"

#include <filesystem>
#include <regex>

#include "core/config.hpp"
#include "core/error.hpp"
#include "io/trajectory_io.hpp"

namespace kestrel::io {
namespace fs = std::filesystem;

std::optional<Calibration> tum_calibration_for(const std::string& folder_name) {
  static const std::regex kWhich(R"((?:freiburg|fr)([123])(?![0-9]))", std::regex::icase);
  std::smatch m;
  if (!std::regex_search(folder_name, m, kWhich)) return std::nullopt;
  Calibration c;
  PinholeCamera& cam = c.camera;
  cam.width = 640;
  cam.height = 480;
  switch (m[1].str()[0]) {
    case '1':
      cam.fx = 517.3, cam.fy = 516.5, cam.cx = 318.6, cam.cy = 255.3;
      cam.model = DistortionModel::kRadTan;
      cam.dist = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
      break;
    case '2':
      cam.fx = 520.9, cam.fy = 521.0, cam.cx = 325.1, cam.cy = 249.7;
      cam.model = DistortionModel::kRadTan;
      cam.dist = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
      break;
    default:
      cam.fx = 535.4, cam.fy = 539.2, cam.cx = 320.1, cam.cy = 247.6;
      cam.model = DistortionModel::kNone;
      break;
  }
  c.depth_scale = 5000.0;
  c.fps = 30.0;
  // TUM's ground truth is the pose of the colour camera's optical centre: body = camera.
  c.T_body_camera = SE3();
  return c;
}

std::vector<StampedVector> read_tum_accelerometer(const std::string& path) {
  return parse_stamped_vectors(TextTable::read(path), "ax ay az");
}

namespace {

RgbdEntry make_entry(const std::string& dir, const ListEntry& color, const std::string& color_list,
                     const ListEntry& depth, const std::string& depth_list) {
  RgbdEntry e;
  e.t = color.t;
  e.color = resolve_path(dir, color.path);
  e.color_list = color_list;
  e.color_line = color.line;
  e.depth = resolve_path(dir, depth.path);
  e.depth_list = depth_list;
  e.depth_line = depth.line;
  return e;
}

}  // namespace

std::unique_ptr<RgbdListSource> open_tum_rgbd(const std::string& dir,
                                              const TumRgbdOptions& options) {
  if (!fs::is_directory(dir)) throw Error::at(dir, 0, "", "not a directory");
  RgbdListSource::Contents c;
  std::string how;

  std::string assoc =
      options.association_file.empty() ? "" : resolve_path(dir, options.association_file);
  if (assoc.empty()) {
    for (const char* name : {"associations.txt", "association.txt"}) {
      if (fs::is_regular_file(fs::path(dir) / name)) {
        assoc = (fs::path(dir) / name).string();
        break;
      }
    }
  }
  if (!assoc.empty()) {
    const TextTable table = TextTable::read(assoc);
    for (const AssociationEntry& a : parse_association(table)) {
      c.frames.push_back(make_entry(dir, a.color, assoc, a.depth, assoc));
    }
    how = "pairs from " + fs::path(assoc).filename().string();
  } else {
    const std::string rgb_path = (fs::path(dir) / "rgb.txt").string();
    const std::string depth_path = (fs::path(dir) / "depth.txt").string();
    const std::vector<ListEntry> rgb = parse_tum_list(TextTable::read(rgb_path));
    const std::vector<ListEntry> depth = parse_tum_list(TextTable::read(depth_path));
    std::vector<Timestamp> ta, tb;
    for (const auto& e : rgb) ta.push_back(e.t);
    for (const auto& e : depth) tb.push_back(e.t);
    const auto pairs = associate(ta, tb, from_seconds(options.max_difference));
    for (const auto& [i, j] : pairs) {
      c.frames.push_back(make_entry(dir, rgb[i], rgb_path, depth[j], depth_path));
    }
    how = std::to_string(pairs.size()) + " of " + std::to_string(rgb.size()) + " rgb / " +
          std::to_string(depth.size()) + " depth images associated";
  }

  std::string calib_from;
  std::string config = options.config_file;
  if (config.empty() && fs::is_regular_file(fs::path(dir) / "calib.yaml")) {
    config = (fs::path(dir) / "calib.yaml").string();
  }
  if (!config.empty()) {
    c.calib = load_config(config).calib;
    calib_from = config;
  } else {
    const std::string name = folder_name(dir);
    auto calib = tum_calibration_for(name);
    if (!calib) {
      throw Error::at(dir, 0, "",
                      "cannot tell the camera: the folder name names no freiburg1/2/3 (fr1/2/3) "
                      "and there is no calib.yaml; give a calibration file (--config)");
    }
    c.calib = *calib;
    calib_from = "TUM Kinect intrinsics for '" + name + "'";
  }

  const std::string gt = (fs::path(dir) / "groundtruth.txt").string();
  if (fs::is_regular_file(gt)) c.ground_truth = read_trajectory(gt);

  c.description = "tum:" + dir + " (RGB-D, " + std::to_string(c.frames.size()) + " frames; " + how +
                  "; calibration: " + calib_from +
                  (c.ground_truth ? "; ground truth" : "; no ground truth") +
                  (fs::is_regular_file(fs::path(dir) / "accelerometer.txt")
                       ? "; accelerometer.txt not streamed (no gyroscope)"
                       : "") +
                  ")";
  return std::make_unique<RgbdListSource>(std::move(c));
}

}  // namespace kestrel::io
