#pragma once
// WebRTC signaling over MQTT (issue 8): the messages a viewer (the station page) and an agent's
// video sender exchange, and their topics. Plain JSON text, version 1, like the commands a page
// sends (comm/SCHEMA.md), so the page needs no encoder of its own:
//
//   kestrel/v1/<agent>/webrtc/<viewer>/to_agent   hello, answer, candidate, keyframe, alive, bye
//   kestrel/v1/<agent>/webrtc/<viewer>/to_viewer  offer, candidate, error
//
// The agent offers (send-only); the page answers. Parsing never throws and never trusts its
// input: every rejection has a reason the sender counts.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>

namespace kestrel::comm {

// An SDP answer is 2-4 KB; anything much larger is not a real one.
constexpr std::size_t kMaxSignalBytes = 64 * 1024;

enum class SignalKind { kHello, kAnswer, kCandidate, kKeyframe, kAlive, kBye };
const char* to_string(SignalKind k);

struct SignalMsg {
  SignalKind kind = SignalKind::kHello;
  // hello
  bool overlay = false;  // draw boxes, features and tracking state for this viewer
  int max_kbps = 0;      // the viewer's cap on the bitrate; 0: the sender's target
  // answer
  std::string sdp;
  // candidate
  int mline = 0;
  std::string candidate;
};

enum class SignalError {
  kOversized,
  kMalformed,
  kUnknownVersion,
  kUnknownKind,
  kBadField,
  kBadTopic,
  kUnknownViewer,
  kTooManyViewers,
  kBadSdp,
};
constexpr int kSignalErrorCount = 9;
const char* to_string(SignalError e);

struct SignalReject {
  SignalError error;
  std::string detail;
};

std::variant<SignalMsg, SignalReject> parse_signal(std::span<const std::uint8_t> payload);
inline std::variant<SignalMsg, SignalReject> parse_signal(std::string_view text) {
  return parse_signal(std::span<const std::uint8_t>(
      reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

// What the sender sends to a viewer.
std::string offer_json(const std::string& sdp, int width, int height, int fps, int kbps,
                       bool overlay);
std::string candidate_json(int mline, const std::string& candidate);
std::string error_json(const std::string& detail);
// And what a viewer sends (the C++ tests play viewer with these).
std::string hello_json(bool overlay, int max_kbps = 0);
std::string answer_json(const std::string& sdp);

// Viewer ids share the agent ids' alphabet ([A-Za-z0-9_-]{1,64}): they are topic levels.
bool valid_viewer_id(std::string_view id);

std::string webrtc_topic(std::string_view agent, std::string_view viewer, bool to_agent);
struct WebRtcTopic {
  std::string agent;
  std::string viewer;
  bool to_agent = true;
};
// nullopt for anything but kestrel/v1/<agent>/webrtc/<viewer>/{to_agent,to_viewer}.
std::optional<WebRtcTopic> parse_webrtc_topic(std::string_view topic);

}  // namespace kestrel::comm
