#include "comm/topics.hpp"

namespace kestrel::comm {

bool valid_agent_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (char c : id) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_';
    if (!ok) return false;
  }
  return true;
}

std::optional<TopicParts> parse_topic(std::string_view topic) {
  if (topic.substr(0, kTopicRoot.size()) != kTopicRoot) return std::nullopt;
  topic.remove_prefix(kTopicRoot.size());
  const auto slash = topic.find('/');
  if (slash == std::string_view::npos) return std::nullopt;
  TopicParts parts{std::string(topic.substr(0, slash)), std::string(topic.substr(slash + 1))};
  if (!valid_agent_id(parts.agent) || parts.stream.empty() ||
      parts.stream.find('/') != std::string::npos) {
    return std::nullopt;
  }
  return parts;
}

}  // namespace kestrel::comm
