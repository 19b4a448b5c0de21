#include "io/kestrel_sequence.hpp"

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_map>

#include "core/config.hpp"
#include "core/error.hpp"
#include "io/dataset_lists.hpp"
#include "io/image_io.hpp"
#include "io/rgbd_list_source.hpp"
#include "io/text_lines.hpp"
#include "io/trajectory_io.hpp"

namespace kestrel::io {
namespace fs = std::filesystem;

namespace {

constexpr const char* kBoxesHeader =
    "#stamp,instance,label,x_min,y_min,x_max,y_max,moving,occluded";
constexpr const char* kImuHeader =
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]";

// %.17g: enough digits that every double reads back to the same bits.
std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

// Labels may hold spaces ("dining table"), and TextTable splits fields on spaces and commas:
// such characters are percent-encoded so that a row keeps one field per column.
bool needs_escape(unsigned char c) {
  return c <= 0x20 || c == 0x7F || c == ',' || c == '%' || c == '#';
}
std::string encode_label(const std::string& s) {
  static const char* const kHex = "0123456789ABCDEF";
  std::string out;
  for (unsigned char c : s) {
    if (needs_escape(c)) {
      out += '%';
      out += kHex[c >> 4];
      out += kHex[c & 15];
    } else {
      out += static_cast<char>(c);
    }
  }
  return out.empty() ? "%00" : out;  // an empty label still needs a field
}
int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

void write_text_file(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error::at(path, 0, "", "cannot create file");
    out << text;
    out.flush();
    if (!out) throw Error::at(path, 0, "", "write error");
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw Error::at(path, 0, "", "cannot rename into place: " + ec.message());
}

std::ofstream open_list(const std::string& path, const std::string& header) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error::at(path, 0, "", "cannot create file");
  out << header << '\n';
  out.flush();
  return out;
}

}  // namespace

struct KestrelSequenceWriter::Files {
  std::ofstream rgb, depth, imu, gt, boxes;
  bool has_frame = false, has_imu = false, has_gt = false;
  Timestamp last_frame = 0, last_imu = 0, last_gt = 0;
  bool closed = false;
};

KestrelSequenceWriter::KestrelSequenceWriter(const std::string& dir, const Calibration& calib)
    : dir_(dir), files_(std::make_unique<Files>()) {
  std::error_code ec;
  for (const char* sub : {"rgb", "depth", "dynamic"}) {
    fs::create_directories(fs::path(dir) / sub, ec);
    if (ec)
      throw Error::at((fs::path(dir) / sub).string(), 0, "", "cannot create: " + ec.message());
  }
  write_text_file((fs::path(dir) / "calib.yaml").string(), to_yaml(calib));
  const fs::path d(dir);
  files_->rgb = open_list((d / "rgb.txt").string(), "# color images\n# timestamp filename");
  files_->depth = open_list((d / "depth.txt").string(), "# depth maps\n# timestamp filename");
  files_->imu = open_list((d / "imu.csv").string(), kImuHeader);
  files_->gt = open_list((d / "groundtruth.txt").string(),
                         "# ground truth trajectory T_w_body\n# timestamp tx ty tz qx qy qz qw");
  files_->boxes = open_list((d / "boxes.csv").string(), kBoxesHeader);
}

KestrelSequenceWriter::~KestrelSequenceWriter() {
  try {
    close();
  } catch (...) {  // a destructor must not throw; close() explicitly to see write errors
  }
}

void KestrelSequenceWriter::write_frame(Timestamp t, const Image& color, const Image& depth,
                                        const Image& dynamic_mask) {
  Files& f = *files_;
  const std::string rgb_list = (fs::path(dir_) / "rgb.txt").string();
  if (f.closed) throw Error::at(rgb_list, 0, "", "write_frame after close()");
  if (f.has_frame && t <= f.last_frame) {
    throw Error::at(rgb_list, 0, "timestamp",
                    "frame stamp " + format_seconds(t) + " is not after the previous frame " +
                        format_seconds(f.last_frame));
  }
  if (color.empty() || color.type != PixelType::kU8 ||
      (color.channels != 1 && color.channels != 3)) {
    throw Error::at(rgb_list, 0, "color", "expected an 8-bit 1- or 3-channel image");
  }
  if (!depth.empty() && (depth.type != PixelType::kU16 || depth.channels != 1)) {
    throw Error::at(rgb_list, 0, "depth", "expected a 16-bit 1-channel image");
  }
  if (!dynamic_mask.empty() &&
      (dynamic_mask.type != PixelType::kU16 || dynamic_mask.channels != 1)) {
    throw Error::at(rgb_list, 0, "dynamic_mask", "expected a 16-bit 1-channel image");
  }
  const std::string name = format_seconds(t) + ".png";
  // Images first, lists after: a list never names an image that is not completely written.
  write_png((fs::path(dir_) / "rgb" / name).string(), color);
  if (!depth.empty()) write_png((fs::path(dir_) / "depth" / name).string(), depth);
  if (!dynamic_mask.empty()) write_png((fs::path(dir_) / "dynamic" / name).string(), dynamic_mask);
  f.rgb << format_seconds(t) << " rgb/" << name << '\n';
  if (!depth.empty()) f.depth << format_seconds(t) << " depth/" << name << '\n';
  f.has_frame = true;
  f.last_frame = t;
  // One flush per frame keeps every index file consistent with the images on disk.
  for (std::ofstream* s : {&f.rgb, &f.depth, &f.imu, &f.gt, &f.boxes}) s->flush();
  if (!f.rgb || !f.depth) throw Error::at(rgb_list, 0, "", "write error");
}

void KestrelSequenceWriter::write_imu(const ImuSample& s) {
  Files& f = *files_;
  const std::string path = (fs::path(dir_) / "imu.csv").string();
  if (f.closed) throw Error::at(path, 0, "", "write_imu after close()");
  if (f.has_imu && s.t <= f.last_imu) {
    throw Error::at(path, 0, "timestamp",
                    "IMU stamp " + std::to_string(s.t) + " ns is not after the previous one " +
                        std::to_string(f.last_imu));
  }
  if (!s.gyro.allFinite() || !s.acc.allFinite()) {
    throw Error::at(path, 0, "", "IMU sample at " + std::to_string(s.t) + " ns is not finite");
  }
  f.imu << s.t;
  for (int i = 0; i < 3; ++i) f.imu << ',' << num(s.gyro[i]);
  for (int i = 0; i < 3; ++i) f.imu << ',' << num(s.acc[i]);
  f.imu << '\n';
  f.has_imu = true;
  f.last_imu = s.t;
  if (!f.imu) throw Error::at(path, 0, "", "write error");
}

void KestrelSequenceWriter::write_ground_truth(Timestamp t, const SE3& T_w_body) {
  Files& f = *files_;
  const std::string path = (fs::path(dir_) / "groundtruth.txt").string();
  if (f.closed) throw Error::at(path, 0, "", "write_ground_truth after close()");
  if (f.has_gt && t <= f.last_gt) {
    throw Error::at(path, 0, "timestamp",
                    "stamp " + format_seconds(t) + " is not after " + format_seconds(f.last_gt));
  }
  const Vec3& p = T_w_body.translation();
  const Quat& q = T_w_body.quaternion();
  f.gt << format_seconds(t) << ' ' << num(p.x()) << ' ' << num(p.y()) << ' ' << num(p.z()) << ' '
       << num(q.x()) << ' ' << num(q.y()) << ' ' << num(q.z()) << ' ' << num(q.w()) << '\n';
  f.has_gt = true;
  f.last_gt = t;
  if (!f.gt) throw Error::at(path, 0, "", "write error");
}

void KestrelSequenceWriter::write_box(const SequenceBox& b) {
  Files& f = *files_;
  const std::string path = (fs::path(dir_) / "boxes.csv").string();
  if (f.closed) throw Error::at(path, 0, "", "write_box after close()");
  f.boxes << format_seconds(b.t) << ',' << b.instance << ',' << encode_label(b.label) << ','
          << num(b.x_min) << ',' << num(b.y_min) << ',' << num(b.x_max) << ',' << num(b.y_max)
          << ',' << (b.moving ? 1 : 0) << ',' << num(b.occluded) << '\n';
  if (!f.boxes) throw Error::at(path, 0, "", "write error");
}

void KestrelSequenceWriter::write_objects(const std::vector<SequenceObject>& objects) {
  write_objects_json((fs::path(dir_) / "objects.json").string(), objects);
}

void KestrelSequenceWriter::write_scenario(const std::string& yaml_text) {
  write_text_file((fs::path(dir_) / "scenario.yaml").string(), yaml_text);
}

void KestrelSequenceWriter::close() {
  if (!files_ || files_->closed) return;
  files_->closed = true;
  std::string failed;
  const std::pair<std::ofstream*, const char*> all[] = {{&files_->rgb, "rgb.txt"},
                                                        {&files_->depth, "depth.txt"},
                                                        {&files_->imu, "imu.csv"},
                                                        {&files_->gt, "groundtruth.txt"},
                                                        {&files_->boxes, "boxes.csv"}};
  for (const auto& [s, name] : all) {
    s->flush();
    s->close();
    if (s->fail() && failed.empty()) failed = name;
  }
  if (!failed.empty()) throw Error::at((fs::path(dir_) / failed).string(), 0, "", "write error");
}

// ---- reading ----

std::vector<SequenceBox> read_boxes(const std::string& path) {
  return parse_boxes(TextTable::read(path));
}

std::vector<SequenceBox> parse_boxes(const TextTable& table) {
  std::vector<SequenceBox> out;
  for (const TextRow& row : table.rows()) {
    table.require_fields(row, 9, "stamp,instance,label,x_min,y_min,x_max,y_max,moving,occluded");
    SequenceBox b;
    b.t = table.seconds(row, 0, "stamp");
    const double inst = table.number(row, 1, "instance");
    if (inst != std::floor(inst) || std::abs(inst) > 2e9) {
      table.fail(row, "instance", "expected an integer id, got '" + row.fields[1] + "'");
    }
    b.instance = static_cast<int>(inst);
    const std::string& enc = row.fields[2];
    if (enc != "%00") {
      for (std::size_t i = 0; i < enc.size(); ++i) {
        if (enc[i] != '%') {
          b.label += enc[i];
          continue;
        }
        const int hi = i + 2 < enc.size() ? hex_value(enc[i + 1]) : -1;
        const int lo = i + 2 < enc.size() ? hex_value(enc[i + 2]) : -1;
        if (hi < 0 || lo < 0) table.fail(row, "label", "bad %-escape in '" + enc + "'");
        b.label += static_cast<char>(hi * 16 + lo);
        i += 2;
      }
    }
    b.x_min = table.number(row, 3, "x_min");
    b.y_min = table.number(row, 4, "y_min");
    b.x_max = table.number(row, 5, "x_max");
    b.y_max = table.number(row, 6, "y_max");
    if (b.x_max < b.x_min || b.y_max < b.y_min) table.fail(row, "x_max", "box has negative size");
    const std::string& mv = row.fields[7];
    if (mv == "1" || mv == "true") {
      b.moving = true;
    } else if (mv == "0" || mv == "false") {
      b.moving = false;
    } else {
      table.fail(row, "moving", "expected 0 or 1, got '" + mv + "'");
    }
    b.occluded = table.number(row, 8, "occluded");
    if (b.occluded < 0.0 || b.occluded > 1.0) table.fail(row, "occluded", "must be in [0, 1]");
    out.push_back(std::move(b));
  }
  return out;
}

namespace {

// nlohmann reports a byte offset; users want a line.
int line_of_offset(const std::string& text, std::size_t offset) {
  int line = 1;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) line += text[i] == '\n';
  return line;
}

}  // namespace

std::vector<SequenceObject> parse_objects_json(const std::string& text, const std::string& name) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw Error::at(name, line_of_offset(text, e.byte), "",
                    std::string("JSON syntax error: ") + e.what());
  } catch (const nlohmann::json::exception& e) {  // e.g. a number too large for a double
    throw Error::at(name, 0, "", std::string("JSON error: ") + e.what());
  }
  if (!j.is_array()) throw Error::at(name, 1, "", "expected a JSON list of objects");
  std::vector<SequenceObject> out;
  for (std::size_t i = 0; i < j.size(); ++i) {
    const nlohmann::json& o = j[i];
    const std::string at = "[" + std::to_string(i) + "]";
    auto fail = [&](const std::string& field, const std::string& msg) -> void {
      throw Error::at(name, 0, at + "." + field, msg);
    };
    if (!o.is_object()) throw Error::at(name, 0, at, "expected an object");
    auto number = [&](const char* key) {
      if (!o.contains(key) || !o[key].is_number()) fail(key, "missing or not a number");
      const double v = o[key].get<double>();
      if (!std::isfinite(v)) fail(key, "must be finite");
      return v;
    };
    auto integer = [&](const char* key) {
      if (!o.contains(key) || !o[key].is_number_integer()) fail(key, "missing or not an integer");
      const auto v = o[key].get<std::int64_t>();
      if (v < INT32_MIN || v > INT32_MAX) fail(key, "out of range");
      return static_cast<int>(v);
    };
    auto vec3 = [&](const char* key) {
      if (!o.contains(key) || !o[key].is_array() || o[key].size() != 3) {
        fail(key, "expected a list of 3 numbers");
      }
      Vec3 v;
      for (int k = 0; k < 3; ++k) {
        const auto& e = o[key][static_cast<std::size_t>(k)];
        if (!e.is_number()) fail(key, "expected a list of 3 numbers");
        v[k] = e.get<double>();
        if (!std::isfinite(v[k])) fail(key, "must be finite");
      }
      return v;
    };
    SequenceObject s;
    s.id = integer("id");
    if (!o.contains("label") || !o["label"].is_string()) fail("label", "missing or not a string");
    s.label = o["label"].get<std::string>();
    s.center = vec3("center");
    s.size = vec3("size");
    s.yaw = number("yaw");
    s.observations = integer("observations");
    s.first_seen = number("first_seen");
    s.last_seen = number("last_seen");
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<SequenceObject> read_objects(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_objects_json(ss.str(), path);
}

void write_objects_json(const std::string& path, const std::vector<SequenceObject>& objects) {
  nlohmann::json j = nlohmann::json::array();
  for (const SequenceObject& o : objects) {
    j.push_back({{"id", o.id},
                 {"label", o.label},
                 {"center", {o.center.x(), o.center.y(), o.center.z()}},
                 {"size", {o.size.x(), o.size.y(), o.size.z()}},
                 {"yaw", o.yaw},
                 {"observations", o.observations},
                 {"first_seen", o.first_seen},
                 {"last_seen", o.last_seen}});
  }
  write_text_file(path, j.dump(2) + "\n");
}

Image read_dynamic_mask(const std::string& dir, Timestamp t) {
  const fs::path p = fs::path(dir) / "dynamic" / (format_seconds(t) + ".png");
  if (!fs::exists(p)) return Image{};
  return load_image(p.string(), ImageKind::kDepth);
}

std::unique_ptr<MeasurementSource> open_kestrel_sequence(const std::string& dir) {
  const fs::path d(dir);
  if (!fs::is_directory(d)) throw Error::at(dir, 0, "", "not a directory");
  RgbdListSource::Contents c;
  c.calib = load_config((d / "calib.yaml").string()).calib;

  const std::string rgb_path = (d / "rgb.txt").string();
  const std::string depth_path = (d / "depth.txt").string();
  const std::vector<ListEntry> rgb = parse_tum_list(TextTable::read(rgb_path));
  std::unordered_map<Timestamp, ListEntry> depth_by_stamp;
  if (fs::exists(depth_path)) {
    for (ListEntry& e : parse_tum_list(TextTable::read(depth_path))) {
      depth_by_stamp.emplace(e.t, std::move(e));
    }
  }
  std::size_t with_depth = 0;
  for (const ListEntry& e : rgb) {
    RgbdEntry r;
    r.t = e.t;
    r.color = resolve_path(dir, e.path);
    r.color_list = rgb_path;
    r.color_line = e.line;
    // The writer gives a frame's colour and depth the same stamp; no association needed.
    if (auto it = depth_by_stamp.find(e.t); it != depth_by_stamp.end()) {
      r.depth = resolve_path(dir, it->second.path);
      r.depth_list = depth_path;
      r.depth_line = it->second.line;
      ++with_depth;
    }
    c.frames.push_back(std::move(r));
  }
  if (fs::exists(d / "imu.csv"))
    c.imu = parse_asl_imu_csv(TextTable::read((d / "imu.csv").string()));
  const std::string gt = (d / "groundtruth.txt").string();
  if (fs::exists(gt) && !TextTable::read(gt).empty()) c.ground_truth = read_trajectory(gt);

  std::ostringstream desc;
  desc << "kestrel:" << dir << " (RGB-D, " << c.frames.size() << " frames, " << with_depth
       << " with depth; " << c.imu.size() << " IMU samples; "
       << (c.ground_truth ? "ground truth" : "no ground truth") << ")";
  c.description = desc.str();
  return std::make_unique<RgbdListSource>(std::move(c));
}

}  // namespace kestrel::io
