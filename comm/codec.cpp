#include "comm/codec.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "comm/topics.hpp"

namespace kestrel::comm {
namespace {

using nlohmann::json;

// Reals go on the wire quantized: CBOR carries them as float32 (5 bytes instead of 9), JSON as
// the shortest decimal of the rounded value. 0.1 mm / 1e-6 is far below any estimator's noise.
double wire_real(double x, double step, Encoding e) {
  if (!std::isfinite(x)) return 0.0;
  const double r = std::round(x / step) * step;
  return e == Encoding::kCbor ? static_cast<double>(static_cast<float>(r)) : r;
}

template <std::size_t N>
json wire_array(const std::array<double, N>& a, double step, Encoding e) {
  json out = json::array();
  for (double x : a) out.push_back(wire_real(x, step, e));
  return out;
}

constexpr double kMetre = 1e-4;
constexpr double kUnit = 1e-6;
constexpr double kRate = 1e-2;

struct Fail {
  DecodeError error;
  std::string detail;
};

const json& field(const json& j, const char* key) {
  auto it = j.find(key);
  if (it == j.end()) throw Fail{DecodeError::kBadField, std::string("missing field '") + key + "'"};
  return *it;
}

double real(const json& j, const char* key) {
  const json& v = field(j, key);
  if (!v.is_number())
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' not a number"};
  const double x = v.get<double>();
  if (!std::isfinite(x))
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' not finite"};
  return x;
}

double real_or(const json& j, const char* key, double fallback) {
  return j.contains(key) ? real(j, key) : fallback;
}

std::int64_t integer(const json& j, const char* key, std::int64_t lo, std::int64_t hi) {
  const json& v = field(j, key);
  if (!v.is_number_integer()) {
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' not an integer"};
  }
  if (v.is_number_unsigned() && v.get<std::uint64_t>() > static_cast<std::uint64_t>(INT64_MAX)) {
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' out of range"};
  }
  const std::int64_t x = v.get<std::int64_t>();
  if (x < lo || x > hi) {
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' out of range"};
  }
  return x;
}

// CBOR text strings must be UTF-8 (RFC 8949) but nlohmann's reader does not check: a string
// that is not would decode here and then throw when the message is written as JSON or shown
// by the page, far from where it came in.
bool valid_utf8(const std::string& s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    int n = 0;
    std::uint32_t cp = 0;
    if (c < 0x80) {
      ++i;
      continue;
    } else if ((c & 0xe0) == 0xc0) {
      n = 1;
      cp = c & 0x1f;
    } else if ((c & 0xf0) == 0xe0) {
      n = 2;
      cp = c & 0x0f;
    } else if ((c & 0xf8) == 0xf0) {
      n = 3;
      cp = c & 0x07;
    } else {
      return false;
    }
    if (i + static_cast<std::size_t>(n) >= s.size()) return false;
    for (int k = 1; k <= n; ++k) {
      const auto cc = static_cast<unsigned char>(s[i + static_cast<std::size_t>(k)]);
      if ((cc & 0xc0) != 0x80) return false;
      cp = (cp << 6) | (cc & 0x3f);
    }
    // Overlong forms, surrogates and code points past Unicode are not UTF-8.
    static constexpr std::uint32_t kMin[4] = {0, 0x80, 0x800, 0x10000};
    if (cp < kMin[n] || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return false;
    i += static_cast<std::size_t>(n) + 1;
  }
  return true;
}

std::string text(const json& j, const char* key, std::size_t max_len = 256) {
  const json& v = field(j, key);
  if (!v.is_string())
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' not a string"};
  std::string s = v.get<std::string>();
  if (s.size() > max_len)
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' too long"};
  if (!valid_utf8(s))
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' not UTF-8"};
  return s;
}

bool flag(const json& j, const char* key) {
  const json& v = field(j, key);
  if (!v.is_boolean())
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' not a boolean"};
  return v.get<bool>();
}

template <std::size_t N>
std::array<double, N> reals(const json& j, const char* key) {
  const json& v = field(j, key);
  if (!v.is_array() || v.size() != N) {
    throw Fail{DecodeError::kBadField,
               std::string("field '") + key + "' not an array of " + std::to_string(N)};
  }
  std::array<double, N> out{};
  for (std::size_t i = 0; i < N; ++i) {
    if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) {
      throw Fail{DecodeError::kBadField, std::string("field '") + key + "' has a non-number"};
    }
    out[i] = v[i].get<double>();
  }
  return out;
}

const json& array(const json& j, const char* key, std::size_t max_size) {
  const json& v = field(j, key);
  if (!v.is_array())
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' not an array"};
  if (v.size() > max_size)
    throw Fail{DecodeError::kBadField, std::string("field '") + key + "' too long"};
  return v;
}

constexpr std::int64_t kU32 = 0xffffffffLL;
constexpr std::int64_t kMaxI64 = INT64_MAX;

json to_json(const Message& msg, Encoding e) {
  json j;
  j["v"] = kSchemaVersion;
  j["k"] = stream_of(msg);
  std::visit(
      [&](const auto& m) {
        using T = std::decay_t<decltype(m)>;
        if constexpr (std::is_same_v<T, PoseMsg>) {
          j["t"] = m.t;
          j["p"] = wire_array(m.p, kMetre, e);
          j["q"] = wire_array(m.q, kUnit, e);
          j["s"] = m.state;
          j["n"] = m.seq;
        } else if constexpr (std::is_same_v<T, StatusMsg>) {
          j["t"] = m.t;
          j["on"] = m.online;
          j["st"] = m.state;
          j["role"] = m.role;
          j["fps"] = wire_real(m.fps, kRate, e);
          j["cpu"] = wire_real(m.cpu, kRate, e);
          j["hp"] = wire_real(m.health, kRate, e);
          j["fr"] = m.frames;
          j["lo"] = m.lost;
          j["dr"] = m.drops;
        } else if constexpr (std::is_same_v<T, DetectionsMsg>) {
          j["t"] = m.t;
          json c = json::object();
          for (const auto& [label, n] : m.counts) c[label] = n;
          j["c"] = c;
          j["df"] = m.dynamic_features;
        } else if constexpr (std::is_same_v<T, ObjectsMsg>) {
          j["t"] = m.t;
          if (m.seq != 0) j["n"] = m.seq;
          j["full"] = m.full;
          json list = json::array();
          for (const auto& o : m.objects) {
            json entry = {{"id", o.id},
                          {"l", o.label},
                          {"c", wire_array(o.center, 1e-3, e)},
                          {"s", wire_array(o.size, 1e-3, e)},
                          {"y", wire_real(o.yaw, 1e-3, e)},
                          {"o", o.observations}};
            if (!o.agents.empty()) entry["a"] = o.agents;
            list.push_back(std::move(entry));
          }
          j["o"] = list;
          j["rm"] = m.removed;
        } else if constexpr (std::is_same_v<T, GridDeltaMsg>) {
          j["t"] = m.t;
          j["n"] = m.seq;
          j["b"] = m.base_seq;
          j["w"] = m.width;
          j["h"] = m.height;
          j["r"] = m.resolution;
          j["o"] = {m.origin[0], m.origin[1]};
          // JSON has no byte strings; the array form is only for debugging tools.
          j["z"] = e == Encoding::kCbor ? json::binary(m.runs_zlib) : json(m.runs_zlib);
        } else if constexpr (std::is_same_v<T, PathMsg>) {
          j["t"] = m.t;
          j["g"] = m.goal_id;
          json pts = json::array();
          for (const auto& p : m.points) {
            pts.push_back(wire_real(p[0], 1e-3, e));
            pts.push_back(wire_real(p[1], 1e-3, e));
          }
          j["xy"] = pts;
          j["done"] = m.reached;
        } else if constexpr (std::is_same_v<T, CommandMsg>) {
          j["id"] = m.id;
          j["t"] = m.t;
          j["c"] = to_string(m.kind);
          if (m.kind == CommandKind::kGoal) j["g"] = {m.goal[0], m.goal[1], m.goal[2]};
          if (m.kind == CommandKind::kTeleop) {
            j["vel"] = m.v;
            j["w"] = m.w;
          }
          if (m.kind == CommandKind::kSaveMap) j["path"] = m.path;
        } else if constexpr (std::is_same_v<T, AckMsg>) {
          j["id"] = m.id;
          j["t"] = m.t;
          j["r"] = to_string(m.result);
          if (!m.detail.empty()) j["d"] = m.detail;
        } else if constexpr (std::is_same_v<T, PingMsg>) {
          j["id"] = m.id;
          j["t0"] = m.t0;
        } else if constexpr (std::is_same_v<T, PongMsg>) {
          j["id"] = m.id;
          j["t0"] = m.t0;
          j["t1"] = m.t1;
          j["t2"] = m.t2;
        }
      },
      msg);
  return j;
}

CommandKind command_kind(const std::string& s) {
  for (auto k : {CommandKind::kGoal, CommandKind::kTeleop, CommandKind::kPause,
                 CommandKind::kResume, CommandKind::kReturnHome, CommandKind::kSaveMap}) {
    if (s == to_string(k)) return k;
  }
  throw Fail{DecodeError::kBadField, "field 'c': unknown command '" + s + "'"};
}

AckResult ack_result(const std::string& s) {
  for (auto r :
       {AckResult::kAccepted, AckResult::kDone, AckResult::kRejected, AckResult::kDuplicate}) {
    if (s == to_string(r)) return r;
  }
  throw Fail{DecodeError::kBadField, "field 'r': unknown result '" + s + "'"};
}

Message from_json(const json& j) {
  if (!j.is_object()) throw Fail{DecodeError::kMalformed, "not a map"};
  auto v = j.find("v");
  if (v == j.end() || !v->is_number_integer())
    throw Fail{DecodeError::kBadField, "missing field 'v'"};
  if (v->get<std::int64_t>() != kSchemaVersion) {
    throw Fail{DecodeError::kUnknownVersion, "version " + v->dump()};
  }
  const std::string kind = text(j, "k", 32);
  if (kind == "pose") {
    PoseMsg m;
    m.t = integer(j, "t", 0, kMaxI64);
    m.p = reals<3>(j, "p");
    m.q = reals<4>(j, "q");
    m.state = static_cast<std::uint8_t>(integer(j, "s", 0, 255));
    m.seq = static_cast<std::uint32_t>(integer(j, "n", 0, kU32));
    return m;
  }
  if (kind == "status") {
    StatusMsg m;
    m.t = integer(j, "t", 0, kMaxI64);
    m.online = flag(j, "on");
    m.state = text(j, "st", 32);
    m.role = text(j, "role", 16);
    m.fps = real(j, "fps");
    m.cpu = real(j, "cpu");
    m.health = real(j, "hp");
    m.frames = static_cast<std::uint64_t>(integer(j, "fr", 0, kMaxI64));
    m.lost = static_cast<std::uint64_t>(integer(j, "lo", 0, kMaxI64));
    m.drops = static_cast<std::uint64_t>(integer(j, "dr", 0, kMaxI64));
    return m;
  }
  if (kind == "detections") {
    DetectionsMsg m;
    m.t = integer(j, "t", 0, kMaxI64);
    const json& c = field(j, "c");
    if (!c.is_object() || c.size() > 256)
      throw Fail{DecodeError::kBadField, "field 'c' not a small map"};
    for (auto it = c.begin(); it != c.end(); ++it) {
      if (!it.value().is_number_unsigned() || it.value().get<std::uint64_t>() > kU32)
        throw Fail{DecodeError::kBadField, "field 'c' count"};
      if (it.key().size() > 64 || !valid_utf8(it.key()))
        throw Fail{DecodeError::kBadField, "field 'c' label"};
      m.counts.emplace_back(it.key(), static_cast<std::uint32_t>(it.value().get<std::uint64_t>()));
    }
    m.dynamic_features = static_cast<std::uint32_t>(integer(j, "df", 0, kU32));
    return m;
  }
  if (kind == "objects") {
    ObjectsMsg m;
    m.t = integer(j, "t", 0, kMaxI64);
    if (j.contains("n")) {
      m.seq =
          static_cast<std::uint64_t>(integer(j, "n", 0, static_cast<std::int64_t>(kMaxObjectsSeq)));
    }
    m.full = flag(j, "full");
    for (const json& o : array(j, "o", 10000)) {
      if (!o.is_object()) throw Fail{DecodeError::kBadField, "field 'o' entry not a map"};
      ObjectInfo info;
      info.id = static_cast<std::uint32_t>(integer(o, "id", 0, kU32));
      info.label = text(o, "l", 64);
      info.center = reals<3>(o, "c");
      info.size = reals<3>(o, "s");
      info.yaw = real(o, "y");
      info.observations = static_cast<std::uint32_t>(integer(o, "o", 0, kU32));
      if (o.contains("a")) {
        for (const json& a : array(o, "a", kMaxAgentsPerObject)) {
          if (!a.is_string() || !valid_agent_id(a.get<std::string>())) {
            throw Fail{DecodeError::kBadField, "field 'a' entry not an agent id"};
          }
          info.agents.push_back(a.get<std::string>());
        }
      }
      m.objects.push_back(std::move(info));
    }
    for (const json& id : array(j, "rm", 10000)) {
      if (!id.is_number_unsigned() || id.get<std::uint64_t>() > 0xffffffffULL) {
        throw Fail{DecodeError::kBadField, "field 'rm' entry not an id"};
      }
      m.removed.push_back(static_cast<std::uint32_t>(id.get<std::uint64_t>()));
    }
    return m;
  }
  if (kind == "grid") {
    GridDeltaMsg m;
    m.t = integer(j, "t", 0, kMaxI64);
    m.seq = static_cast<std::uint32_t>(integer(j, "n", 0, kU32));
    m.base_seq = static_cast<std::uint32_t>(integer(j, "b", 0, kU32));
    m.width = static_cast<std::uint32_t>(integer(j, "w", 0, 1 << 15));
    m.height = static_cast<std::uint32_t>(integer(j, "h", 0, 1 << 15));
    m.resolution = real(j, "r");
    if (m.resolution <= 0) throw Fail{DecodeError::kBadField, "field 'r' not positive"};
    m.origin = reals<2>(j, "o");
    const json& z = field(j, "z");
    if (z.is_binary()) {
      m.runs_zlib.assign(z.get_binary().begin(), z.get_binary().end());
    } else if (z.is_array()) {
      for (const json& b : z) {
        if (!b.is_number_unsigned() || b.get<std::uint64_t>() > 255) {
          throw Fail{DecodeError::kBadField, "field 'z' entry not a byte"};
        }
        m.runs_zlib.push_back(static_cast<std::uint8_t>(b.get<std::uint64_t>()));
      }
    } else {
      throw Fail{DecodeError::kBadField, "field 'z' not bytes"};
    }
    return m;
  }
  if (kind == "path") {
    PathMsg m;
    m.t = integer(j, "t", 0, kMaxI64);
    m.goal_id = text(j, "g", 64);
    const json& xy = array(j, "xy", 200000);
    if (xy.size() % 2 != 0) throw Fail{DecodeError::kBadField, "field 'xy' odd length"};
    for (std::size_t i = 0; i < xy.size(); i += 2) {
      if (!xy[i].is_number() || !xy[i + 1].is_number()) {
        throw Fail{DecodeError::kBadField, "field 'xy' has a non-number"};
      }
      m.points.push_back({xy[i].get<double>(), xy[i + 1].get<double>()});
    }
    m.reached = flag(j, "done");
    return m;
  }
  if (kind == "cmd") {
    CommandMsg m;
    m.id = text(j, "id", 64);
    if (m.id.empty()) throw Fail{DecodeError::kBadField, "field 'id' empty"};
    m.t = integer(j, "t", 0, kMaxI64);
    m.kind = command_kind(text(j, "c", 32));
    if (m.kind == CommandKind::kGoal) m.goal = reals<3>(j, "g");
    if (m.kind == CommandKind::kTeleop) {
      m.v = real(j, "vel");
      m.w = real_or(j, "w", 0.0);
    }
    if (m.kind == CommandKind::kSaveMap) m.path = text(j, "path", 1024);
    return m;
  }
  if (kind == "ack") {
    AckMsg m;
    m.id = text(j, "id", 64);
    m.t = integer(j, "t", 0, kMaxI64);
    m.result = ack_result(text(j, "r", 32));
    if (j.contains("d")) m.detail = text(j, "d", 1024);
    return m;
  }
  if (kind == "ping") {
    PingMsg m;
    m.id = static_cast<std::uint32_t>(integer(j, "id", 0, kU32));
    m.t0 = integer(j, "t0", INT64_MIN + 1, kMaxI64);
    return m;
  }
  if (kind == "pong") {
    PongMsg m;
    m.id = static_cast<std::uint32_t>(integer(j, "id", 0, kU32));
    m.t0 = integer(j, "t0", INT64_MIN + 1, kMaxI64);
    m.t1 = integer(j, "t1", INT64_MIN + 1, kMaxI64);
    m.t2 = integer(j, "t2", INT64_MIN + 1, kMaxI64);
    return m;
  }
  throw Fail{DecodeError::kUnknownKind, "kind '" + kind + "'"};
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

const char* to_string(DecodeError e) {
  switch (e) {
    case DecodeError::kOversized:
      return "oversized";
    case DecodeError::kMalformed:
      return "malformed";
    case DecodeError::kUnknownVersion:
      return "unknown version";
    case DecodeError::kUnknownKind:
      return "unknown kind";
    case DecodeError::kBadField:
      return "bad field";
  }
  return "?";
}

std::vector<std::uint8_t> encode(const Message& m, Encoding e) {
  const json j = to_json(m, e);
  if (e == Encoding::kCbor) return json::to_cbor(j);
  const std::string s = j.dump();
  return {s.begin(), s.end()};
}

Decoder::Decoder(LogFn log) : log_(std::move(log)) {
  if (!log_) log_ = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
}

std::optional<Message> Decoder::decode(std::span<const std::uint8_t> bytes,
                                       std::string_view where) {
  if (bytes.size() > kMaxMessageBytes) {
    reject(DecodeError::kOversized, where, std::to_string(bytes.size()) + " bytes");
    return std::nullopt;
  }
  if (bytes.empty()) {
    reject(DecodeError::kMalformed, where, "empty payload");
    return std::nullopt;
  }
  try {
    // A CBOR map starts with major type 5 (0xa0..0xbf); JSON text with '{' (or whitespace).
    const bool is_cbor = bytes[0] >= 0xa0 && bytes[0] <= 0xbf;
    json j = is_cbor ? json::from_cbor(bytes.begin(), bytes.end(), true, false)
                     : json::parse(bytes.begin(), bytes.end(), nullptr, false);
    if (j.is_discarded()) throw Fail{DecodeError::kMalformed, is_cbor ? "bad CBOR" : "bad JSON"};
    Message m = from_json(j);
    ok_.fetch_add(1, std::memory_order_relaxed);
    return m;
  } catch (const Fail& f) {
    reject(f.error, where, f.detail);
  } catch (const std::exception& ex) {  // nlohmann's type and parse errors
    reject(DecodeError::kMalformed, where, ex.what());
  }
  return std::nullopt;
}

void Decoder::reject(DecodeError e, std::string_view where, const std::string& detail) {
  const int i = static_cast<int>(e);
  errors_[i].fetch_add(1, std::memory_order_relaxed);
  const std::int64_t now = now_ns();
  std::int64_t last = last_log_ns_[i].load(std::memory_order_relaxed);
  if (now - last < kNanosPerSecond && last != 0) return;
  if (!last_log_ns_[i].compare_exchange_strong(last, now)) return;
  std::string line = "kestrel comm: rejected message";
  if (!where.empty()) line.append(" on ").append(where);
  line.append(": ").append(to_string(e)).append(": ").append(detail);
  line.append(" (").append(std::to_string(errors_[i].load())).append(" so far)");
  log_(line);
}

DecodeCounts Decoder::counts() const {
  DecodeCounts c;
  c.ok = ok_.load();
  c.oversized = errors_[0].load();
  c.malformed = errors_[1].load();
  c.unknown_version = errors_[2].load();
  c.unknown_kind = errors_[3].load();
  c.bad_field = errors_[4].load();
  return c;
}

}  // namespace kestrel::comm
