#pragma once
// mapd: the team map server. Subscribes to every agent's objects (kestrel/v1/+/objects: the
// retained snapshot first, then deltas), keeps each agent's table, rebuilds the team map
// (comm/team_map.hpp) when something changed and publishes it as a retained full snapshot on
// kestrel/v1/team/objects, at most once per period. Bad input never reaches the map: messages
// the codec rejects (oversized, malformed, unknown version or kind, bad fields), other kinds on
// an objects topic, and objects from agents outside the configured team are counted and logged.
// The MQTT loop thread only stores; the owner's thread builds and publishes (spin_once).
#include <chrono>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "comm/codec.hpp"
#include "comm/mqtt_client.hpp"
#include "comm/team_map.hpp"

namespace kestrel::comm {

struct MapdOptions {
  MqttOptions mqtt;                                   // user "mapd" (ACL: writes kestrel/v1/team/#)
  std::vector<std::string> agents;                    // the team; empty: any agent id
  std::vector<std::pair<std::string, Pose4>> starts;  // T_team_agent priors, in this order
  TeamMapOptions team;
  double publish_period_s = 1.0;
  Encoding encoding = Encoding::kCbor;
};

struct MapdCounts {
  std::uint64_t received = 0;       // messages on objects topics
  std::uint64_t applied = 0;        // objects messages folded into an agent's table
  std::uint64_t stale = 0;          // objects messages older than one already applied
  std::uint64_t unknown_agent = 0;  // from an agent outside --agents
  std::uint64_t wrong_kind = 0;     // decoded, but not an objects message
  std::uint64_t published = 0;      // team snapshots sent
  DecodeCounts decode;
  std::uint64_t rejected() const { return unknown_agent + wrong_kind + decode.rejected(); }
};

class Mapd {
 public:
  explicit Mapd(MapdOptions options);
  ~Mapd();  // disconnects; the retained team snapshot stays for late viewers

  void start();
  bool wait_connected(std::chrono::milliseconds timeout) const;
  // Rebuilds and publishes when an agent's table changed and a period has passed since the last
  // snapshot (force: now, whatever the period). True when it published.
  bool spin_once(bool force = false);

  TeamMapResult last() const;  // the latest team map built
  MapdCounts counts() const;
  MqttClient& client() { return *client_; }

 private:
  void handle(const std::string& topic, std::span<const std::uint8_t> payload);

  MapdOptions options_;
  Decoder decoder_;
  std::unique_ptr<MqttClient> client_;
  std::set<std::string> team_;
  mutable std::mutex mutex_;
  TeamMap map_;
  bool dirty_ = false;
  TeamMapResult last_;
  MapdCounts counts_;
  std::set<std::string> logged_unknown_;
  std::chrono::steady_clock::time_point last_publish_{};
  std::uint64_t next_seq_ = first_objects_seq(wall_clock_ns());
};

}  // namespace kestrel::comm
