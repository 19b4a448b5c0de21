#pragma once
// A thin RAII client over libmosquitto (MQTT v5). comm/ is the one layer besides pipeline/ that
// runs a thread: libmosquitto's network loop (mosquitto_loop_start) reads, writes, keeps the
// connection alive and reconnects with bounded back-off. Message handlers run on that thread
// and must return quickly.
//
// Delivery: QoS 0 messages (poses: latest wins) are sent while connected and dropped, counted,
// while not. QoS 1 messages (commands, acknowledgements, objects) stay in a bounded outbox
// until the broker acknowledges them (PUBACK) and are re-sent after every reconnect, so a broker
// restart loses none; a receiver may therefore see one twice and suppresses duplicates by id
// (comm/command_dedup.hpp). When the outbox is full the oldest entry is dropped and counted.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace kestrel::comm {

struct MqttOptions {
  std::string host = "127.0.0.1";
  int port = 1883;
  std::string client_id;  // also the default username
  std::string username;
  std::string password;
  int keepalive_s = 5;  // libmosquitto's minimum
  // Kestrel does not rely on broker sessions (libmosquitto 2.0 drops the v5 session-expiry
  // property on automatic reconnects): commands are re-sent until acknowledged and objects are
  // re-published as a retained snapshot on every connect. Hence a clean start by default.
  bool clean_start = true;
  std::string will_topic;  // empty: no last will
  std::vector<std::uint8_t> will_payload;
  bool will_retain = true;
  std::size_t outbox_limit = 4096;
  unsigned reconnect_min_s = 1;  // libmosquitto's back-off, doubled up to the maximum
  unsigned reconnect_max_s = 2;
};

// Parses "mqtt://HOST:PORT" (or "HOST:PORT"); throws kestrel::Error naming the field `flag`.
void parse_broker_url(const std::string& url, const std::string& flag, MqttOptions& options);

struct MqttStats {
  std::uint64_t sent = 0;             // handed to the socket (QoS 0 and QoS 1, re-sends included)
  std::uint64_t acknowledged = 0;     // QoS 1 PUBACKs with a success reason code
  std::uint64_t refused = 0;          // PUBACKs with a failure code (e.g. 0x87 not authorized)
  std::uint64_t dropped_offline = 0;  // QoS 0 while disconnected
  std::uint64_t outbox_overflow = 0;  // QoS 1 dropped because the outbox was full
  std::uint64_t received = 0;
  std::uint64_t connects = 0;  // successful CONNACKs (1 + reconnects)
  std::uint64_t disconnects = 0;
};

class MqttClient {
 public:
  using Handler = std::function<void(const std::string& topic, std::span<const std::uint8_t>)>;

  explicit MqttClient(MqttOptions options);
  ~MqttClient();  // disconnects cleanly (no last will) and stops the loop thread
  MqttClient(const MqttClient&) = delete;
  MqttClient& operator=(const MqttClient&) = delete;

  // Before start(): the handler of every received message, and the subscriptions that are
  // renewed on every connect.
  void on_message(Handler handler);
  void subscribe(const std::string& pattern, int qos);
  // Called on the loop thread after every successful connect, once the outbox is re-sent
  // (e.g. to re-publish a retained snapshot).
  void on_connected(std::function<void()> hook);

  // Connects asynchronously and starts the loop thread; reconnects by itself from then on.
  void start();
  // True once connected and every subscription is acknowledged (nothing sent to us is missed).
  bool wait_connected(std::chrono::milliseconds timeout) const;
  bool connected() const;
  // The broker's last CONNACK reason code: 0 accepted, 0x86 bad user name or password,
  // 0x87 not authorized; -1 before any answer. Refused credentials are not retried.
  int connack_code() const;

  // False only when the message was dropped (QoS 0 offline, or the outbox evicted it).
  bool publish(const std::string& topic, std::vector<std::uint8_t> payload, int qos,
               bool retain = false);
  std::size_t outbox_size() const;
  MqttStats stats() const;

  // Stops now. with_will = true ends the session with reason 0x04 so the broker publishes the
  // last will (a clean "going offline" that still tells everybody).
  void stop(bool with_will = false);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Wall-clock nanoseconds (system_clock): what crosses machines in pings and stamps.
std::int64_t wall_clock_ns();

}  // namespace kestrel::comm
