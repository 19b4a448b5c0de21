#include "comm/station_link.hpp"

#include <cstdio>

#include "comm/topics.hpp"

namespace kestrel::comm {

StationLink::StationLink(StationLinkOptions options) : options_(std::move(options)) {
  if (options_.mqtt.client_id.empty()) options_.mqtt.client_id = "station";
  client_ = std::make_unique<MqttClient>(options_.mqtt);
  client_->on_message(
      [this](const std::string& topic, std::span<const std::uint8_t> p) { handle(topic, p); });
  client_->subscribe(std::string(kTopicRoot) + "+/#", 1);
}

StationLink::~StationLink() {
  if (retry_thread_.joinable()) {
    retry_thread_.request_stop();
    cv_.notify_all();
    retry_thread_.join();
  }
  client_->stop(false);
}

void StationLink::start() {
  client_->start();
  retry_thread_ = std::jthread([this](std::stop_token st) { retry_loop(st); });
}

bool StationLink::wait_connected(std::chrono::milliseconds timeout) const {
  return client_->wait_connected(timeout);
}

void StationLink::on_pose(
    std::function<void(const std::string&, const PoseMsg&, std::int64_t)> fn) {
  std::lock_guard lock(mutex_);
  pose_fn_ = std::move(fn);
}

std::optional<std::string> StationLink::send_command(const std::string& agent, CommandMsg cmd) {
  std::vector<std::uint8_t> bytes;
  {
    std::lock_guard lock(mutex_);
    if (!agents_.count(agent)) {
      ++counts_.commands_unknown_agent;
      std::fprintf(stderr, "kestrel station: command for unknown agent '%s' not sent\n",
                   agent.c_str());
      return std::nullopt;
    }
    if (cmd.id.empty()) {
      // Unique across station restarts: the wall clock plus a counter.
      cmd.id = "c" + std::to_string(wall_clock_ns()) + "-" + std::to_string(next_command_++);
    }
    cmd.t = wall_clock_ns();
    bytes = encode(cmd, options_.encoding);
    const auto now = std::chrono::steady_clock::now();
    pending_[cmd.id] = PendingCommand{agent, bytes, now, now};
    ++counts_.commands_sent;
  }
  client_->publish(topic_of(agent, "cmd"), std::move(bytes), 1);
  return cmd.id;
}

std::optional<AckMsg> StationLink::ack(const std::string& id) const {
  std::lock_guard lock(mutex_);
  auto it = acks_.find(id);
  if (it == acks_.end()) return std::nullopt;
  return it->second;
}

std::optional<AckMsg> StationLink::wait_ack(const std::string& id,
                                            std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mutex_);
  if (!cv_.wait_for(lock, timeout, [&] { return acks_.count(id) > 0; })) return std::nullopt;
  return acks_.at(id);
}

void StationLink::ping(const std::string& agent) {
  PingMsg p;
  {
    std::lock_guard lock(mutex_);
    p.id = next_ping_++;
  }
  p.t0 = wall_clock_ns();
  client_->publish(topic_of(agent, "ping"), encode(p, options_.encoding), 0);
}

std::map<std::string, AgentView> StationLink::agents() const {
  std::lock_guard lock(mutex_);
  return agents_;
}

std::optional<AgentView> StationLink::agent(const std::string& id) const {
  std::lock_guard lock(mutex_);
  auto it = agents_.find(id);
  if (it == agents_.end()) return std::nullopt;
  return it->second;
}

bool StationLink::wait_for(const std::function<bool(const std::map<std::string, AgentView>&)>& pred,
                           std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mutex_);
  return cv_.wait_for(lock, timeout, [&] { return pred(agents_); });
}

StationCounts StationLink::counts() const {
  std::lock_guard lock(mutex_);
  StationCounts c = counts_;
  c.decode = decoder_.counts();
  return c;
}

void StationLink::handle(const std::string& topic, std::span<const std::uint8_t> payload) {
  const std::int64_t now = wall_clock_ns();
  const auto parts = parse_topic(topic);
  if (!parts) return;
  // Commands and pings are the station's own traffic, echoed by the wildcard subscription.
  if (parts->stream == "cmd" || parts->stream == "ping") return;
  // An empty retained payload clears a topic; it is not a message.
  if (payload.empty()) return;
  auto msg = decoder_.decode(payload, topic);
  if (!msg) return;
  std::function<void(const std::string&, const PoseMsg&, std::int64_t)> pose_fn;
  {
    std::lock_guard lock(mutex_);
    AgentView& a = agents_[parts->agent];
    a.id = parts->agent;
    a.last_heard_wall_ns = now;
    if (auto* p = std::get_if<PoseMsg>(&*msg)) {
      if (a.have_pose) {
        if (p->seq <= a.pose.seq) {
          ++a.poses_out_of_order;
        } else {
          a.poses_missed += p->seq - a.pose.seq - 1;
        }
      }
      a.pose = *p;
      a.have_pose = true;
      ++a.poses;
      pose_fn = pose_fn_;
    } else if (auto* s = std::get_if<StatusMsg>(&*msg)) {
      a.status = *s;
      a.have_status = true;
    } else if (auto* o = std::get_if<ObjectsMsg>(&*msg)) {
      if (!objects_message_is_new(a.objects_seq, o->seq)) {
        ++a.objects_stale;
        return;
      }
      if (o->seq != 0) a.objects_seq = o->seq;
      if (o->full) a.objects.clear();
      for (const auto& obj : o->objects) a.objects[obj.id] = obj;
      for (auto id : o->removed) a.objects.erase(id);
    } else if (auto* path = std::get_if<PathMsg>(&*msg)) {
      // Stamped by the agent's clock when planned: a path re-sent late (after a broker crash,
      // behind what followed it) must not replace a newer goal's.
      if (a.path && path->t < a.path->t) {
        ++a.paths_stale;
        return;
      }
      a.path = *path;
    } else if (auto* ack = std::get_if<AckMsg>(&*msg)) {
      ++counts_.acks;
      pending_.erase(ack->id);
      // The first answer counts: a later "duplicate" only confirms it.
      if (!acks_.count(ack->id) || acks_[ack->id].result == AckResult::kDuplicate) {
        acks_[ack->id] = *ack;
      }
    } else if (auto* pong = std::get_if<PongMsg>(&*msg)) {
      a.clock.add(clock_sample(*pong, now));
    }
  }
  cv_.notify_all();
  if (pose_fn) pose_fn(parts->agent, std::get<PoseMsg>(*msg), now);
}

void StationLink::retry_loop(std::stop_token stop) {
  auto last_ping = std::chrono::steady_clock::now();
  while (!stop.stop_requested()) {
    std::vector<std::pair<std::string, std::vector<std::uint8_t>>> resend;
    std::vector<std::string> ping_targets;
    {
      std::unique_lock lock(mutex_);
      cv_.wait_for(lock, std::chrono::milliseconds(100), [&] { return stop.stop_requested(); });
      if (stop.stop_requested()) break;
      const auto now = std::chrono::steady_clock::now();
      for (auto it = pending_.begin(); it != pending_.end();) {
        if (now - it->second.first > options_.give_up) {
          ++counts_.commands_expired;
          std::fprintf(stderr, "kestrel station: command %s to '%s' never acknowledged\n",
                       it->first.c_str(), it->second.agent.c_str());
          it = pending_.erase(it);
          continue;
        }
        // Only while connected: offline, the client's outbox already holds the last copy.
        if (now - it->second.last > options_.retry && client_->connected()) {
          it->second.last = now;
          resend.emplace_back(topic_of(it->second.agent, "cmd"), it->second.bytes);
          ++counts_.command_resends;
        }
        ++it;
      }
      if (options_.ping_period.count() > 0 && now - last_ping > options_.ping_period) {
        last_ping = now;
        for (const auto& [id, a] : agents_) {
          if (a.have_status && a.status.online) ping_targets.push_back(id);
        }
      }
    }
    for (auto& [topic, bytes] : resend) client_->publish(topic, std::move(bytes), 1);
    for (const auto& id : ping_targets) ping(id);
  }
}

}  // namespace kestrel::comm
