#include "comm/schema.hpp"

namespace kestrel::comm {

const char* to_string(CommandKind k) {
  switch (k) {
    case CommandKind::kGoal:
      return "goal";
    case CommandKind::kTeleop:
      return "teleop";
    case CommandKind::kPause:
      return "pause";
    case CommandKind::kResume:
      return "resume";
    case CommandKind::kReturnHome:
      return "home";
    case CommandKind::kSaveMap:
      return "save_map";
  }
  return "?";
}

const char* to_string(AckResult r) {
  switch (r) {
    case AckResult::kAccepted:
      return "accepted";
    case AckResult::kDone:
      return "done";
    case AckResult::kRejected:
      return "rejected";
    case AckResult::kDuplicate:
      return "duplicate";
  }
  return "?";
}

const char* stream_of(const Message& m) {
  static constexpr const char* kNames[] = {"pose", "status", "detections", "objects", "grid",
                                           "path", "cmd",    "ack",        "ping",    "pong"};
  static_assert(std::variant_size_v<Message> == std::size(kNames));
  return kNames[m.index()];
}

}  // namespace kestrel::comm
