#pragma once
// An agent's video over WebRTC with its signaling over MQTT: a WebRtcSender plus its own MQTT
// connection (client id "<agent>:webrtc", the agent's credentials), subscribed to
// kestrel/v1/<agent>/webrtc/+/to_agent. A connection of its own keeps SDP bursts and viewers'
// keep-alives out of the telemetry connection's queue and leaves AgentLink's will untouched.
#include <chrono>
#include <memory>

#include "comm/agent_link.hpp"
#include "comm/mqtt_client.hpp"
#include "comm/webrtc_sender.hpp"

namespace kestrel::comm {

class WebRtcVideoLink {
 public:
  // link: the agent's id and broker settings (as for AgentLink). Throws kestrel::Error for a
  // bad id or when GStreamer's video elements are missing.
  WebRtcVideoLink(const AgentLinkOptions& link, VideoOptions video);
  ~WebRtcVideoLink();

  void start();
  bool wait_connected(std::chrono::milliseconds timeout) const;
  WebRtcSender& sender() { return *sender_; }
  MqttStats mqtt_stats() const { return client_->stats(); }

 private:
  std::string id_;
  std::unique_ptr<MqttClient> client_;
  std::unique_ptr<WebRtcSender> sender_;
};

}  // namespace kestrel::comm
