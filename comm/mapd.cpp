#include "comm/mapd.hpp"

#include <cstdio>

#include "comm/topics.hpp"
#include "core/error.hpp"

namespace kestrel::comm {

Mapd::Mapd(MapdOptions options)
    : options_(std::move(options)),
      team_(options_.agents.begin(), options_.agents.end()),
      map_(options_.team) {
  for (const auto& a : options_.agents) {
    if (!valid_agent_id(a) || a == kTeamName) {
      throw Error::at("command line", 0, "agents", "'" + a + "' is not a usable agent id");
    }
  }
  for (const auto& [agent, pose] : options_.starts) {
    if (!team_.empty() && !team_.count(agent)) {
      throw Error::at("command line", 0, "start", "'" + agent + "' is not one of --agents");
    }
    map_.set_start(agent, pose);
  }
  MqttOptions mqtt = options_.mqtt;
  if (mqtt.client_id.empty()) mqtt.client_id = mqtt.username.empty() ? "mapd" : mqtt.username;
  client_ = std::make_unique<MqttClient>(mqtt);
  client_->on_message(
      [this](const std::string& topic, std::span<const std::uint8_t> p) { handle(topic, p); });
  client_->subscribe(std::string(kTopicRoot) + "+/objects", 1);
}

Mapd::~Mapd() { client_->stop(false); }

void Mapd::start() { client_->start(); }

bool Mapd::wait_connected(std::chrono::milliseconds timeout) const {
  return client_->wait_connected(timeout);
}

void Mapd::handle(const std::string& topic, std::span<const std::uint8_t> payload) {
  const auto parts = parse_topic(topic);
  if (!parts || parts->stream != "objects") return;
  if (parts->agent == kTeamName) return;  // our own snapshot, echoed by the wildcard
  if (payload.empty()) return;            // a cleared retained topic, not a message
  {
    std::lock_guard lock(mutex_);
    ++counts_.received;
    if (!team_.empty() && !team_.count(parts->agent)) {
      ++counts_.unknown_agent;
      // One line per stranger: a misconfigured agent must not flood the log.
      if (logged_unknown_.insert(parts->agent).second) {
        std::fprintf(stderr, "kestrel mapd: rejected objects from unknown agent '%s' on %s\n",
                     parts->agent.c_str(), topic.c_str());
      }
      return;
    }
  }
  auto msg = decoder_.decode(payload, topic);
  if (!msg) return;  // counted and logged by the decoder
  std::lock_guard lock(mutex_);
  const auto* objects = std::get_if<ObjectsMsg>(&*msg);
  if (!objects) {
    if (counts_.wrong_kind++ == 0) {
      std::fprintf(stderr, "kestrel mapd: rejected a '%s' message on %s\n", stream_of(*msg),
                   topic.c_str());
    }
    return;
  }
  if (!map_.apply(parts->agent, *objects)) {
    ++counts_.stale;
    return;
  }
  ++counts_.applied;
  dirty_ = true;
}

bool Mapd::spin_once(bool force) {
  ObjectsMsg snap;
  {
    std::lock_guard lock(mutex_);
    const auto now = std::chrono::steady_clock::now();
    if (!dirty_) return false;
    if (!force && now - last_publish_ < std::chrono::duration<double>(options_.publish_period_s)) {
      return false;
    }
    dirty_ = false;
    last_publish_ = now;
    last_ = map_.build();
    snap.objects = last_.objects;
    ++counts_.published;
    snap.seq = next_seq_++;
    snap.t = wall_clock_ns();
    snap.full = true;
    // Retained: a station that opens later gets the team map at once. Sent under the lock so
    // that seq follows the outbox order.
    client_->publish(topic_of(kTeamName, "objects"), encode(snap, options_.encoding), 1, true);
  }
  return true;
}

TeamMapResult Mapd::last() const {
  std::lock_guard lock(mutex_);
  return last_;
}

MapdCounts Mapd::counts() const {
  std::lock_guard lock(mutex_);
  MapdCounts c = counts_;
  c.decode = decoder_.counts();
  return c;
}

}  // namespace kestrel::comm
