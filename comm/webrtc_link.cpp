#include "comm/webrtc_link.hpp"

#include "comm/topics.hpp"
#include "core/error.hpp"

namespace kestrel::comm {

WebRtcVideoLink::WebRtcVideoLink(const AgentLinkOptions& link, VideoOptions video) : id_(link.id) {
  if (!valid_agent_id(id_)) {
    throw Error::at("command line", 0, "id",
                    "agent id '" + id_ + "' must be 1-64 of [A-Za-z0-9_-]");
  }
  MqttOptions mqtt = link.mqtt;
  // ':' is outside the agent-id alphabet, so this client id never collides with an agent's.
  mqtt.client_id = id_ + ":webrtc";
  if (mqtt.username.empty()) mqtt.username = id_;
  mqtt.will_topic.clear();
  client_ = std::make_unique<MqttClient>(mqtt);
  MqttClient* client = client_.get();
  const std::string id = id_;
  sender_ = std::make_unique<WebRtcSender>(
      video, [client, id](const std::string& viewer, const std::string& json) {
        client->publish(webrtc_topic(id, viewer, false),
                        std::vector<std::uint8_t>(json.begin(), json.end()), 1);
      });
  WebRtcSender* sender = sender_.get();
  client_->on_message([sender, id](const std::string& topic, std::span<const std::uint8_t> p) {
    const auto t = parse_webrtc_topic(topic);
    if (!t || !t->to_agent || t->agent != id) {
      sender->count_reject(SignalError::kBadTopic);
      return;
    }
    sender->handle(t->viewer, p);
  });
  client_->subscribe(webrtc_topic(id_, "+", true), 1);
}

WebRtcVideoLink::~WebRtcVideoLink() {
  // The sender's callbacks publish through the client: close the viewers first.
  client_->stop(false);
  sender_.reset();
}

void WebRtcVideoLink::start() { client_->start(); }

bool WebRtcVideoLink::wait_connected(std::chrono::milliseconds timeout) const {
  return client_->wait_connected(timeout);
}

}  // namespace kestrel::comm
