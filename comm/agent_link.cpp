#include "comm/agent_link.hpp"

#include <thread>

#include "comm/topics.hpp"
#include "core/error.hpp"

namespace kestrel::comm {

AgentLink::AgentLink(AgentLinkOptions options, CommandHandler handler)
    : options_(std::move(options)), handler_(std::move(handler)) {
  if (!valid_agent_id(options_.id)) {
    throw Error::at("command line", 0, "id",
                    "agent id '" + options_.id + "' must be 1-64 of [A-Za-z0-9_-]");
  }
  if (options_.id == kTeamName) {
    throw Error::at("command line", 0, "id",
                    std::string("agent id '") + kTeamName + "' is reserved for mapd's team map");
  }
  MqttOptions mqtt = options_.mqtt;
  mqtt.client_id = options_.id;
  if (mqtt.username.empty()) mqtt.username = options_.id;
  StatusMsg offline;
  offline.online = false;
  offline.state = "offline";
  offline.role = options_.role;
  mqtt.will_topic = topic_of(options_.id, "status");
  mqtt.will_payload = encode(offline, options_.encoding);
  mqtt.will_retain = true;
  client_ = std::make_unique<MqttClient>(mqtt);
  client_->on_message(
      [this](const std::string& topic, std::span<const std::uint8_t> p) { handle(topic, p); });
  client_->subscribe(topic_of(options_.id, "cmd"), 1);
  client_->subscribe(topic_of(options_.id, "ping"), 0);
  client_->on_connected([this] { publish_objects_snapshot(); });
}

AgentLink::~AgentLink() {
  StatusMsg offline;
  offline.t = wall_clock_ns();
  offline.online = false;
  offline.state = "offline";
  offline.role = options_.role;
  if (client_->connected()) {
    client_->publish(topic_of(options_.id, "status"), encode(offline, options_.encoding), 1, true);
    // Give the PUBACK a moment so the retained offline status is really stored.
    for (int i = 0; i < 50 && client_->outbox_size() > 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  client_->stop(false);
}

void AgentLink::start() { client_->start(); }

bool AgentLink::wait_connected(std::chrono::milliseconds timeout) const {
  return client_->wait_connected(timeout);
}

void AgentLink::publish(const Message& m) {
  const std::string topic = topic_of(options_.id, stream_of(m));
  int qos = 1;
  bool retain = false;
  if (std::holds_alternative<PoseMsg>(m) || std::holds_alternative<DetectionsMsg>(m)) qos = 0;
  if (std::holds_alternative<StatusMsg>(m)) retain = true;
  if (const auto* objects = std::get_if<ObjectsMsg>(&m)) {
    // Numbered and handed to the client under one lock, so that seq follows the outbox order
    // even when the reconnect hook sends a snapshot meanwhile.
    std::lock_guard lock(mutex_);
    if (objects->full) objects_.clear();
    for (const auto& o : objects->objects) objects_[o.id] = o;
    for (auto id : objects->removed) objects_.erase(id);
    ObjectsMsg numbered = *objects;
    numbered.seq = next_objects_seq_++;
    client_->publish(topic, encode(Message{std::move(numbered)}, options_.encoding), qos, retain);
    return;
  }
  if (const auto* status = std::get_if<StatusMsg>(&m); status && status->role.empty()) {
    StatusMsg s = *status;  // the link knows the role; telemetry sources need not
    s.role = options_.role;
    client_->publish(topic, encode(s, options_.encoding), qos, retain);
    return;
  }
  client_->publish(topic, encode(m, options_.encoding), qos, retain);
}

void AgentLink::publish_objects_snapshot() {
  ObjectsMsg snap;
  snap.t = wall_clock_ns();
  snap.full = true;
  std::lock_guard lock(mutex_);
  for (const auto& [id, o] : objects_) snap.objects.push_back(o);
  snap.seq = next_objects_seq_++;
  client_->publish(topic_of(options_.id, "objects"), encode(snap, options_.encoding), 1, true);
}

void AgentLink::handle(const std::string& topic, std::span<const std::uint8_t> payload) {
  const Timestamp t_recv = wall_clock_ns();
  auto msg = decoder_.decode(payload, topic);
  if (!msg) return;
  if (const auto* ping = std::get_if<PingMsg>(&*msg)) {
    PongMsg pong{ping->id, ping->t0, t_recv, 0};
    {
      std::lock_guard lock(mutex_);
      ++counts_.pings;
    }
    pong.t2 = wall_clock_ns();
    client_->publish(topic_of(options_.id, "pong"), encode(pong, options_.encoding), 0);
    return;
  }
  const auto* cmd = std::get_if<CommandMsg>(&*msg);
  if (!cmd) return;  // only commands and pings are addressed to an agent
  bool first = false;
  {
    std::lock_guard lock(mutex_);
    first = dedup_.first_time(cmd->id);
    ++(first ? counts_.commands_executed : counts_.commands_duplicate);
  }
  AckMsg ack;
  if (first) {
    ack = handler_ ? handler_(*cmd) : AckMsg{cmd->id, 0, AckResult::kRejected, "no handler"};
  } else {
    ack.result = AckResult::kDuplicate;
  }
  ack.id = cmd->id;
  ack.t = wall_clock_ns();
  client_->publish(topic_of(options_.id, "ack"), encode(ack, options_.encoding), 1);
}

AgentLinkCounts AgentLink::counts() const {
  std::lock_guard lock(mutex_);
  AgentLinkCounts c = counts_;
  c.decode = decoder_.counts();
  return c;
}

}  // namespace kestrel::comm
