#pragma once
// Topic layout kestrel/v1/<agent>/<stream>: an agent publishes pose, status, detections,
// objects, grid, path, ack and pong under its own name and reads cmd and ping there; the
// station reads kestrel/v1/+/# and alone publishes cmd and ping (scripts/mosquitto/ ACL).
#include <optional>
#include <string>
#include <string_view>

namespace kestrel::comm {

constexpr std::string_view kTopicRoot = "kestrel/v1/";

// Agent ids are user names in the broker's ACL (%u): letters, digits, '-' and '_', 1..64.
bool valid_agent_id(std::string_view id);

inline std::string topic_of(std::string_view agent, std::string_view stream) {
  std::string t(kTopicRoot);
  t.append(agent).append("/").append(stream);
  return t;
}

struct TopicParts {
  std::string agent;
  std::string stream;
};
// nullopt for topics outside kestrel/v1/<agent>/<stream>.
std::optional<TopicParts> parse_topic(std::string_view topic);

}  // namespace kestrel::comm
