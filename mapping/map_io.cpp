#include "mapping/map_io.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <ostream>
#include <type_traits>
#include <utility>

#include "core/error.hpp"

namespace kestrel::mapping {
namespace {

static_assert(std::endian::native == std::endian::little,
              "map.bin is little-endian; a big-endian host needs byte swapping here");

constexpr char kMagic[8] = {'K', 'S', 'T', 'R', 'L', 'M', 'A', 'P'};
constexpr char kEnd[4] = {'K', 'E', 'N', 'D'};
// A keyframe's image side in pixels at most: its feature grid is sized from width and height, so
// a corrupt size must not allocate gigabytes (a 2^31-pixel-wide keyframe asked for ~10 GB).
constexpr int kMaxImageSide = 16384;

// Appends to a buffer: serialize_map takes the whole buffer, save_map hands it to the file each
// time it passes kFlushBytes, so that saving a long run's map never holds a second copy of it.
class Writer {
 public:
  static constexpr std::size_t kFlushBytes = std::size_t{1} << 18;  // 256 KiB

  explicit Writer(std::ostream* sink = nullptr) : sink_(sink) {}

  template <typename T>
  void put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes(&v, sizeof(T));
  }
  void bytes(const void* p, std::size_t n) {
    out_.append(static_cast<const char*>(p), n);
    if (sink_ && out_.size() >= kFlushBytes) flush();
  }
  void descriptor(const OrbDescriptor& d) {
    std::uint8_t b[32];
    d.to_bytes(b);
    bytes(b, sizeof(b));
  }
  void vec3(const Vec3& v) {
    put(v.x());
    put(v.y());
    put(v.z());
  }
  void flush() {
    sink_->write(out_.data(), static_cast<std::streamsize>(out_.size()));
    out_.clear();
  }
  std::string take() { return std::move(out_); }

 private:
  std::ostream* sink_;
  std::string out_;
};

class Reader {
 public:
  Reader(const std::string& bytes, const std::string& name) : in_(bytes), name_(name) {}

  template <typename T>
  T get(const char* field) {
    static_assert(std::is_trivially_copyable_v<T>);
    T v;
    std::memcpy(&v, take(sizeof(T), field), sizeof(T));
    return v;
  }
  const char* take(std::size_t n, const char* field) {
    if (in_.size() - pos_ < n) {
      throw fail(field, "truncated: needs " + std::to_string(n) + " bytes at offset " +
                            std::to_string(pos_) + ", the file has " + std::to_string(in_.size()));
    }
    const char* p = in_.data() + pos_;
    pos_ += n;
    return p;
  }
  OrbDescriptor descriptor(const char* field) {
    return OrbDescriptor::from_bytes(reinterpret_cast<const std::uint8_t*>(take(32, field)));
  }
  Vec3 vec3(const char* field) {
    const double x = get<double>(field), y = get<double>(field), z = get<double>(field);
    return Vec3(x, y, z);
  }
  // A count of items of at least min_item_bytes each: larger than what is left means the file
  // is corrupt, and must not become a giant allocation.
  std::size_t count(const char* field, std::size_t min_item_bytes) {
    const auto n = get<std::uint64_t>(field);
    if (n > (in_.size() - pos_) / min_item_bytes) {
      throw fail(field, "count " + std::to_string(n) + " at offset " + std::to_string(pos_ - 8) +
                            " exceeds the remaining bytes (truncated or corrupt)");
    }
    return static_cast<std::size_t>(n);
  }
  std::size_t offset() const { return pos_; }
  bool at_end() const { return pos_ == in_.size(); }
  Error fail(const std::string& field, const std::string& msg) const {
    return Error::at(name_, 0, field, msg);
  }

 private:
  const std::string& in_;
  const std::string& name_;
  std::size_t pos_ = 0;
};

void write_keyframe(Writer& w, const Keyframe& kf) {
  w.put<std::int64_t>(kf.id);
  w.put<std::int64_t>(kf.t);
  w.vec3(kf.T_w_c.translation());
  const Quat& q = kf.T_w_c.quaternion();
  w.put(q.x());
  w.put(q.y());
  w.put(q.z());
  w.put(q.w());
  const FrameFeatures& f = kf.features;
  w.put<std::int32_t>(f.width);
  w.put<std::int32_t>(f.height);
  w.put<float>(f.scale_factor);
  w.put<std::int32_t>(f.levels);
  w.put<std::uint64_t>(f.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    const tracking::Keypoint& k = f.keypoints[i];
    w.put(k.px.x());
    w.put(k.px.y());
    w.put(k.un.x());
    w.put(k.un.y());
    w.put(k.angle);
    w.put(k.response);
    w.put<std::int32_t>(k.level);
    w.descriptor(f.descriptors[i]);
    w.put(f.depth[i]);
    w.vec3(f.points_c[i]);
    w.put(static_cast<std::uint8_t>(f.status[i]));
    w.put<std::int64_t>(kf.point_of_feature[i]);
  }
  w.put<std::uint64_t>(kf.connections.size());
  for (const auto& [other, weight] : kf.connections) {
    w.put<std::int64_t>(other);
    w.put<std::int32_t>(weight);
  }
}

Keyframe read_keyframe(Reader& r) {
  Keyframe kf;
  kf.id = r.get<std::int64_t>("keyframe.id");
  kf.t = r.get<std::int64_t>("keyframe.stamp");
  const Vec3 t = r.vec3("keyframe.translation");
  const double qx = r.get<double>("keyframe.rotation"), qy = r.get<double>("keyframe.rotation"),
               qz = r.get<double>("keyframe.rotation"), qw = r.get<double>("keyframe.rotation");
  Quat q(qw, qx, qy, qz);
  if (!t.allFinite() || !q.coeffs().allFinite() || std::abs(q.norm() - 1.0) > 1e-6) {
    throw r.fail("keyframe.rotation", "keyframe " + std::to_string(kf.id) +
                                          " has a non-finite pose or a non-unit quaternion");
  }
  kf.T_w_c = SE3(q.normalized(), t);
  FrameFeatures& f = kf.features;
  f.t = kf.t;
  f.width = r.get<std::int32_t>("keyframe.width");
  f.height = r.get<std::int32_t>("keyframe.height");
  f.scale_factor = r.get<float>("keyframe.scale_factor");
  f.levels = r.get<std::int32_t>("keyframe.levels");
  if (f.width <= 0 || f.height <= 0 || f.width > kMaxImageSide || f.height > kMaxImageSide ||
      !(f.scale_factor > 1.0f) || f.levels <= 0) {
    throw r.fail("keyframe.width", "keyframe " + std::to_string(kf.id) +
                                       " has a bad image size or pyramid (" +
                                       std::to_string(f.width) + "x" + std::to_string(f.height) +
                                       ", " + std::to_string(f.levels) + " levels)");
  }
  const std::size_t n = r.count("keyframe.features", 32 + 8 * 8 + 4 * 3 + 1 + 8);
  f.keypoints.resize(n);
  f.descriptors.resize(n);
  f.depth.resize(n);
  f.points_c.resize(n);
  f.status.resize(n);
  kf.point_of_feature.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    tracking::Keypoint& k = f.keypoints[i];
    const double px = r.get<double>("feature.px"), py = r.get<double>("feature.px");
    const double ux = r.get<double>("feature.un"), uy = r.get<double>("feature.un");
    k.px = Vec2(px, py);
    k.un = Vec2(ux, uy);
    k.angle = r.get<float>("feature.angle");
    k.response = r.get<float>("feature.response");
    k.level = r.get<std::int32_t>("feature.level");
    if (k.level < 0 || k.level >= f.levels) {
      throw r.fail("feature.level", "level " + std::to_string(k.level) + " of keyframe " +
                                        std::to_string(kf.id) + " is outside its pyramid");
    }
    f.descriptors[i] = r.descriptor("feature.descriptor");
    f.depth[i] = r.get<double>("feature.depth");
    f.points_c[i] = r.vec3("feature.point");
    const auto status = r.get<std::uint8_t>("feature.status");
    if (status > static_cast<std::uint8_t>(tracking::FeatureStatus::kUnknown)) {
      throw r.fail("feature.status", "unknown status " + std::to_string(status));
    }
    f.status[i] = static_cast<tracking::FeatureStatus>(status);
    kf.point_of_feature[i] = r.get<std::int64_t>("feature.map_point");
  }
  const std::size_t c = r.count("keyframe.connections", 12);
  for (std::size_t i = 0; i < c; ++i) {
    const auto other = r.get<std::int64_t>("connection.keyframe");
    kf.connections[other] = r.get<std::int32_t>("connection.weight");
  }
  f.build_grid();
  return kf;
}

void write_point(Writer& w, const MapPoint& p) {
  w.put<std::int64_t>(p.id);
  w.vec3(p.p_w);
  w.descriptor(p.descriptor);
  w.vec3(p.normal);
  w.put<std::int64_t>(p.first_keyframe);
  w.put<std::int32_t>(p.visible);
  w.put<std::int32_t>(p.found);
  w.put(p.min_distance);
  w.put(p.max_distance);
  w.put<std::uint64_t>(p.observations.size());
  for (const auto& [kf, feature] : p.observations) {
    w.put<std::int64_t>(kf);
    w.put<std::int32_t>(feature);
  }
}

MapPoint read_point(Reader& r) {
  MapPoint p;
  p.id = r.get<std::int64_t>("point.id");
  p.p_w = r.vec3("point.position");
  if (!p.p_w.allFinite()) {
    throw r.fail("point.position", "point " + std::to_string(p.id) + " is not finite");
  }
  p.descriptor = r.descriptor("point.descriptor");
  p.normal = r.vec3("point.normal");
  p.first_keyframe = r.get<std::int64_t>("point.first_keyframe");
  p.visible = r.get<std::int32_t>("point.visible");
  p.found = r.get<std::int32_t>("point.found");
  p.min_distance = r.get<double>("point.min_distance");
  p.max_distance = r.get<double>("point.max_distance");
  const std::size_t n = r.count("point.observations", 12);
  for (std::size_t i = 0; i < n; ++i) {
    const auto kf = r.get<std::int64_t>("observation.keyframe");
    p.observations[kf] = r.get<std::int32_t>("observation.feature");
  }
  return p;
}

// Every link must point at something that exists, both ways, or the tracker would index out of
// range later.
void check_links(const std::map<KeyframeId, Keyframe>& kfs,
                 const std::unordered_map<PointId, MapPoint>& pts, const Reader& r) {
  for (const auto& [id, p] : pts) {
    if (p.observations.empty()) {
      throw r.fail("point.observations", "point " + std::to_string(id) + " has no observation");
    }
    for (const auto& [kid, feature] : p.observations) {
      const auto it = kfs.find(kid);
      if (it == kfs.end() || feature < 0 ||
          static_cast<std::size_t>(feature) >= it->second.point_of_feature.size() ||
          it->second.point_of_feature[static_cast<std::size_t>(feature)] != id) {
        throw r.fail("observation", "point " + std::to_string(id) + " claims feature " +
                                        std::to_string(feature) + " of keyframe " +
                                        std::to_string(kid) + ", which does not link back");
      }
    }
  }
  for (const auto& [kid, kf] : kfs) {
    for (std::size_t i = 0; i < kf.point_of_feature.size(); ++i) {
      const PointId pid = kf.point_of_feature[i];
      if (pid == kNoPoint) continue;
      const auto it = pts.find(pid);
      if (it == pts.end() || !it->second.observations.contains(kid)) {
        throw r.fail("feature.map_point", "keyframe " + std::to_string(kid) + " feature " +
                                              std::to_string(i) + " links to point " +
                                              std::to_string(pid) + ", which does not link back");
      }
    }
    for (const auto& [other, weight] : kf.connections) {
      (void)weight;
      if (!kfs.contains(other)) {
        throw r.fail("connection.keyframe", "keyframe " + std::to_string(kid) +
                                                " connects to missing keyframe " +
                                                std::to_string(other));
      }
    }
  }
}

void write_map(Writer& w, const Map& map) {
  w.bytes(kMagic, sizeof(kMagic));
  w.put<std::uint32_t>(kMapFormatVersion);
  w.put<std::uint64_t>(map.num_keyframes());
  for (const auto& [id, kf] : map.keyframes()) write_keyframe(w, kf);
  // Points in id order, so that equal maps give equal bytes.
  std::map<PointId, const MapPoint*> ordered;
  for (const auto& [id, p] : map.points()) ordered.emplace(id, &p);
  w.put<std::uint64_t>(ordered.size());
  for (const auto& [id, p] : ordered) write_point(w, *p);
  w.bytes(kEnd, sizeof(kEnd));
}

}  // namespace

std::string serialize_map(const Map& map) {
  Writer w;
  write_map(w, map);
  return w.take();
}

Map deserialize_map(const std::string& bytes, const std::string& name) {
  Reader r(bytes, name);
  if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    throw r.fail("magic", "not a Kestrel map (expected the bytes \"KSTRLMAP\" at the start)");
  }
  r.take(sizeof(kMagic), "magic");
  const auto version = r.get<std::uint32_t>("version");
  if (version != kMapFormatVersion) {
    throw r.fail("version", "map format version " + std::to_string(version) +
                                " is not supported (this build reads version " +
                                std::to_string(kMapFormatVersion) + ")");
  }
  std::map<KeyframeId, Keyframe> kfs;
  const std::size_t nk = r.count("keyframes", 8 * 9 + 4 * 4 + 8 + 8);
  for (std::size_t i = 0; i < nk; ++i) {
    Keyframe kf = read_keyframe(r);
    const KeyframeId id = kf.id;
    if (id < 0 || !kfs.emplace(id, std::move(kf)).second) {
      throw r.fail("keyframe.id", "keyframe id " + std::to_string(id) + " is negative or repeated");
    }
  }
  std::unordered_map<PointId, MapPoint> pts;
  const std::size_t np = r.count("points", 8 * 11 + 32 + 4 * 2);
  pts.reserve(np);
  for (std::size_t i = 0; i < np; ++i) {
    MapPoint p = read_point(r);
    const PointId id = p.id;
    if (id < 0 || !pts.emplace(id, std::move(p)).second) {
      throw r.fail("point.id", "point id " + std::to_string(id) + " is negative or repeated");
    }
  }
  if (std::memcmp(r.take(sizeof(kEnd), "end"), kEnd, sizeof(kEnd)) != 0) {
    throw r.fail("end", "missing end marker at offset " + std::to_string(r.offset() - 4));
  }
  if (!r.at_end()) {
    throw r.fail("end", std::to_string(bytes.size() - r.offset()) +
                            " unexpected bytes after the end marker");
  }
  check_links(kfs, pts, r);
  Map map;
  map.restore(std::move(kfs), std::move(pts));
  return map;
}

void save_map(const std::string& path, const Map& map) {
  // Written beside the target and renamed over it once complete: a failed save (full disk,
  // killed process) leaves the previous map.bin as it was.
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error::at(tmp, 0, "", "cannot open for writing");
    Writer w(&out);
    write_map(w, map);
    w.flush();
    out.close();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw Error::at(tmp, 0, "", "write failed");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw Error::at(path, 0, "", "cannot replace it with " + tmp + ": " + ec.message());
  }
}

Map load_map(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open the map file");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return deserialize_map(bytes, path);
}

void write_keyframes_tum(const std::string& path, const Map& map, const SE3& T_body_camera) {
  std::ofstream out(path);
  if (!out) throw Error::at(path, 0, "", "cannot open for writing");
  const SE3 T_camera_body = T_body_camera.inverse();
  char line[256];
  for (const auto& [id, kf] : map.keyframes()) {
    const SE3 T_w_b = kf.T_w_c * T_camera_body;
    const Vec3& t = T_w_b.translation();
    const Quat& q = T_w_b.quaternion();
    std::snprintf(line, sizeof(line), "%.9f %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n",
                  static_cast<double>(kf.t) * 1e-9, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(),
                  q.w());
    out << line;
  }
  if (!out) throw Error::at(path, 0, "", "write failed");
}

void write_points_ply(const std::string& path, const Map& map) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error::at(path, 0, "", "cannot open for writing");
  std::map<PointId, const MapPoint*> ordered;
  for (const auto& [id, p] : map.points()) ordered.emplace(id, &p);
  out << "ply\nformat binary_little_endian 1.0\ncomment Kestrel sparse map, world frame, "
         "metres\nelement vertex "
      << ordered.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar "
         "observations\nend_header\n";
  for (const auto& [id, p] : ordered) {
    const float xyz[3] = {static_cast<float>(p->p_w.x()), static_cast<float>(p->p_w.y()),
                          static_cast<float>(p->p_w.z())};
    const auto obs = static_cast<std::uint8_t>(std::min<std::size_t>(p->observations.size(), 255));
    out.write(reinterpret_cast<const char*>(xyz), sizeof(xyz));
    out.write(reinterpret_cast<const char*>(&obs), 1);
  }
  if (!out) throw Error::at(path, 0, "", "write failed");
}

}  // namespace kestrel::mapping
