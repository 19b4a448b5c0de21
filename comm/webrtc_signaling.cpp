#include "comm/webrtc_signaling.hpp"

#include <nlohmann/json.hpp>

#include "comm/topics.hpp"

namespace kestrel::comm {
namespace {

constexpr int kSignalVersion = 1;

SignalReject reject(SignalError e, std::string detail) { return {e, std::move(detail)}; }

}  // namespace

const char* to_string(SignalKind k) {
  switch (k) {
    case SignalKind::kHello:
      return "hello";
    case SignalKind::kAnswer:
      return "answer";
    case SignalKind::kCandidate:
      return "candidate";
    case SignalKind::kKeyframe:
      return "keyframe";
    case SignalKind::kAlive:
      return "alive";
    case SignalKind::kBye:
      return "bye";
  }
  return "?";
}

const char* to_string(SignalError e) {
  switch (e) {
    case SignalError::kOversized:
      return "oversized";
    case SignalError::kMalformed:
      return "malformed";
    case SignalError::kUnknownVersion:
      return "unknown version";
    case SignalError::kUnknownKind:
      return "unknown kind";
    case SignalError::kBadField:
      return "bad field";
    case SignalError::kBadTopic:
      return "bad topic";
    case SignalError::kUnknownViewer:
      return "unknown viewer";
    case SignalError::kTooManyViewers:
      return "too many viewers";
    case SignalError::kBadSdp:
      return "bad sdp";
  }
  return "?";
}

std::variant<SignalMsg, SignalReject> parse_signal(std::span<const std::uint8_t> payload) {
  if (payload.size() > kMaxSignalBytes) {
    return reject(SignalError::kOversized, std::to_string(payload.size()) + " bytes");
  }
  const auto j = nlohmann::json::parse(payload.begin(), payload.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) return reject(SignalError::kMalformed, "not a JSON map");
  const auto v = j.find("v");
  if (v == j.end() || !v->is_number_integer() || v->get<int>() != kSignalVersion) {
    return reject(SignalError::kUnknownVersion, "v");
  }
  const auto k = j.find("k");
  if (k == j.end() || !k->is_string()) return reject(SignalError::kBadField, "k");
  const std::string kind = k->get<std::string>();
  SignalMsg m;
  const auto text = [&](const char* key, std::string& out) {
    const auto it = j.find(key);
    if (it == j.end() || !it->is_string() || it->get_ref<const std::string&>().empty()) {
      return false;
    }
    out = it->get<std::string>();
    return true;
  };
  if (kind == "hello") {
    m.kind = SignalKind::kHello;
    if (const auto o = j.find("overlay"); o != j.end()) {
      if (!o->is_boolean()) return reject(SignalError::kBadField, "overlay");
      m.overlay = o->get<bool>();
    }
    if (const auto b = j.find("max_kbps"); b != j.end()) {
      if (!b->is_number_integer() || b->get<std::int64_t>() < 0 ||
          b->get<std::int64_t>() > 100000) {
        return reject(SignalError::kBadField, "max_kbps");
      }
      m.max_kbps = b->get<int>();
    }
  } else if (kind == "answer") {
    m.kind = SignalKind::kAnswer;
    if (!text("sdp", m.sdp)) return reject(SignalError::kBadField, "sdp");
  } else if (kind == "candidate") {
    m.kind = SignalKind::kCandidate;
    const auto ml = j.find("m");
    if (ml == j.end() || !ml->is_number_integer() || ml->get<std::int64_t>() < 0 ||
        ml->get<std::int64_t>() > 16) {
      return reject(SignalError::kBadField, "m");
    }
    m.mline = ml->get<int>();
    if (!text("c", m.candidate)) return reject(SignalError::kBadField, "c");
  } else if (kind == "keyframe") {
    m.kind = SignalKind::kKeyframe;
  } else if (kind == "alive") {
    m.kind = SignalKind::kAlive;
  } else if (kind == "bye") {
    m.kind = SignalKind::kBye;
  } else {
    return reject(SignalError::kUnknownKind, kind.substr(0, 32));
  }
  return m;
}

std::string offer_json(const std::string& sdp, int width, int height, int fps, int kbps,
                       bool overlay) {
  return nlohmann::json{{"v", kSignalVersion}, {"k", "offer"}, {"sdp", sdp},   {"w", width},
                        {"h", height},         {"fps", fps},   {"kbps", kbps}, {"overlay", overlay}}
      .dump();
}

std::string candidate_json(int mline, const std::string& candidate) {
  return nlohmann::json{{"v", kSignalVersion}, {"k", "candidate"}, {"m", mline}, {"c", candidate}}
      .dump();
}

std::string error_json(const std::string& detail) {
  return nlohmann::json{{"v", kSignalVersion}, {"k", "error"}, {"d", detail}}.dump();
}

std::string hello_json(bool overlay, int max_kbps) {
  nlohmann::json j{{"v", kSignalVersion}, {"k", "hello"}, {"overlay", overlay}};
  if (max_kbps > 0) j["max_kbps"] = max_kbps;
  return j.dump();
}

std::string answer_json(const std::string& sdp) {
  return nlohmann::json{{"v", kSignalVersion}, {"k", "answer"}, {"sdp", sdp}}.dump();
}

bool valid_viewer_id(std::string_view id) { return valid_agent_id(id); }

std::string webrtc_topic(std::string_view agent, std::string_view viewer, bool to_agent) {
  std::string t(kTopicRoot);
  t.append(agent).append("/webrtc/").append(viewer).append(to_agent ? "/to_agent" : "/to_viewer");
  return t;
}

std::optional<WebRtcTopic> parse_webrtc_topic(std::string_view topic) {
  if (topic.substr(0, kTopicRoot.size()) != kTopicRoot) return std::nullopt;
  topic.remove_prefix(kTopicRoot.size());
  std::string_view parts[4];
  for (int i = 0; i < 4; ++i) {
    const auto slash = topic.find('/');
    if (i < 3) {
      if (slash == std::string_view::npos) return std::nullopt;
      parts[i] = topic.substr(0, slash);
      topic.remove_prefix(slash + 1);
    } else {
      if (slash != std::string_view::npos) return std::nullopt;
      parts[i] = topic;
    }
  }
  if (!valid_agent_id(parts[0]) || parts[1] != "webrtc" || !valid_viewer_id(parts[2])) {
    return std::nullopt;
  }
  if (parts[3] != "to_agent" && parts[3] != "to_viewer") return std::nullopt;
  return WebRtcTopic{std::string(parts[0]), std::string(parts[2]), parts[3] == "to_agent"};
}

}  // namespace kestrel::comm
