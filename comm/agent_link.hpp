#pragma once
// The agent's end of the link: publishes its telemetry under kestrel/v1/<id>/..., executes the
// station's commands exactly once (dedup by id, acknowledged every time) and answers pings.
// Its last will is a retained `offline` status, so a killed agent shows as offline.
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "comm/codec.hpp"
#include "comm/command_dedup.hpp"
#include "comm/mqtt_client.hpp"
#include "comm/schema.hpp"

namespace kestrel::comm {

struct AgentLinkOptions {
  std::string id;  // also the broker user name (ACL %u)
  std::string role = "ugv";
  MqttOptions mqtt;  // host, port, password; client id and will are filled in
  Encoding encoding = Encoding::kCbor;
};

// Executes a command (on the MQTT loop thread: keep it short, hand long work to the owner)
// and says how it went: kAccepted / kDone / kRejected with a detail.
using CommandHandler = std::function<AckMsg(const CommandMsg&)>;

struct AgentLinkCounts {
  std::uint64_t commands_executed = 0;
  std::uint64_t commands_duplicate = 0;
  std::uint64_t pings = 0;
  DecodeCounts decode;
};

class AgentLink {
 public:
  AgentLink(AgentLinkOptions options, CommandHandler handler);
  ~AgentLink();  // publishes a retained offline status and disconnects cleanly

  void start();
  bool wait_connected(std::chrono::milliseconds timeout) const;

  // Picks topic and QoS from the message kind: pose and detections at QoS 0 (latest wins),
  // everything else at QoS 1 through the outbox; status is retained. Objects messages also
  // update the agent's object table, re-published as a retained full snapshot on every
  // (re)connect so that a station that was away catches up.
  void publish(const Message& m);

  // The object table as a retained full snapshot: sent on every (re)connect and, by the agent,
  // now and then, so that a subscriber that joins late (mapd, a station) starts from the whole
  // table and the deltas that follow apply to it.
  void publish_objects_snapshot();

  const std::string& id() const { return options_.id; }
  AgentLinkCounts counts() const;
  MqttClient& client() { return *client_; }

 private:
  void handle(const std::string& topic, std::span<const std::uint8_t> payload);

  AgentLinkOptions options_;
  CommandHandler handler_;
  Decoder decoder_;
  std::unique_ptr<MqttClient> client_;
  mutable std::mutex mutex_;
  CommandDedup dedup_;
  std::map<std::uint32_t, ObjectInfo> objects_;
  std::uint64_t next_objects_seq_ = first_objects_seq(wall_clock_ns());
  AgentLinkCounts counts_;
};

}  // namespace kestrel::comm
