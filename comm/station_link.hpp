#pragma once
// The station's end of the link (also what tests and benchmarks use to watch agents): keeps a
// view of every agent heard from (status, last pose, order and gaps of poses, objects, path,
// round trip and clock offset) and sends commands that are re-sent until acknowledged. Runs a
// small retry/ping thread next to libmosquitto's loop thread.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "comm/clock_sync.hpp"
#include "comm/codec.hpp"
#include "comm/mqtt_client.hpp"
#include "comm/schema.hpp"

namespace kestrel::comm {

struct AgentView {
  std::string id;
  bool have_status = false;
  StatusMsg status;
  bool have_pose = false;
  PoseMsg pose;
  std::uint64_t poses = 0;
  std::uint64_t poses_out_of_order = 0;  // seq not above the previous one
  std::uint64_t poses_missed = 0;        // gaps in seq (QoS 0 drops)
  std::map<std::uint32_t, ObjectInfo> objects;
  std::uint64_t objects_seq = 0;    // of the last objects message applied
  std::uint64_t objects_stale = 0;  // objects messages ignored as older (re-sent late)
  std::optional<PathMsg> path;
  std::uint64_t paths_stale = 0;  // path messages older than the one held (re-sent late)
  ClockSync clock;
  std::int64_t last_heard_wall_ns = 0;
};

struct StationLinkOptions {
  MqttOptions mqtt;  // user "station" (the only one the ACL lets publish commands)
  Encoding encoding = Encoding::kCbor;
  std::chrono::milliseconds retry{1000};  // re-send an unacknowledged command this often
  std::chrono::milliseconds give_up{60000};
  std::chrono::milliseconds ping_period{0};  // 0: only explicit ping()
};

struct StationCounts {
  std::uint64_t commands_sent = 0;
  std::uint64_t command_resends = 0;
  std::uint64_t commands_unknown_agent = 0;
  std::uint64_t commands_expired = 0;
  std::uint64_t acks = 0;
  DecodeCounts decode;
};

class StationLink {
 public:
  explicit StationLink(StationLinkOptions options);
  ~StationLink();

  void start();
  bool wait_connected(std::chrono::milliseconds timeout) const;

  // Sends a command to an agent the station has heard from; an empty id gets a fresh one.
  // Returns the id, or nullopt for an unknown agent (counted and logged).
  std::optional<std::string> send_command(const std::string& agent, CommandMsg cmd);
  std::optional<AckMsg> ack(const std::string& id) const;
  std::optional<AckMsg> wait_ack(const std::string& id, std::chrono::milliseconds timeout) const;

  void ping(const std::string& agent);
  std::map<std::string, AgentView> agents() const;
  std::optional<AgentView> agent(const std::string& id) const;
  bool wait_for(const std::function<bool(const std::map<std::string, AgentView>&)>& pred,
                std::chrono::milliseconds timeout) const;
  StationCounts counts() const;

  // Called for every decoded pose with the station's wall-clock arrival time (latency probes).
  void on_pose(std::function<void(const std::string&, const PoseMsg&, std::int64_t)> fn);

  MqttClient& client() { return *client_; }

 private:
  struct PendingCommand {
    std::string agent;
    std::vector<std::uint8_t> bytes;
    std::chrono::steady_clock::time_point first, last;
  };
  void handle(const std::string& topic, std::span<const std::uint8_t> payload);
  void retry_loop(std::stop_token stop);

  StationLinkOptions options_;
  Decoder decoder_;
  std::unique_ptr<MqttClient> client_;
  mutable std::mutex mutex_;
  mutable std::condition_variable cv_;
  std::map<std::string, AgentView> agents_;
  std::map<std::string, PendingCommand> pending_;
  std::map<std::string, AckMsg> acks_;
  StationCounts counts_;
  std::uint32_t next_ping_ = 1;
  std::uint64_t next_command_ = 1;
  std::function<void(const std::string&, const PoseMsg&, std::int64_t)> pose_fn_;
  std::jthread retry_thread_;
};

}  // namespace kestrel::comm
