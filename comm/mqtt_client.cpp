#include "comm/mqtt_client.hpp"

#include <mosquitto.h>
#include <mqtt_protocol.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <mutex>

#include "core/error.hpp"

namespace kestrel::comm {
namespace {

void init_library() {
  static std::once_flag once;
  std::call_once(once, [] { mosquitto_lib_init(); });
}

struct Pending {
  std::string topic;
  std::vector<std::uint8_t> payload;
  bool retain = false;
  int mid = -1;  // libmosquitto message id while in flight; -1 not sent on this connection
};

}  // namespace

void parse_broker_url(const std::string& url, const std::string& flag, MqttOptions& options) {
  std::string rest = url;
  const std::string scheme = "mqtt://";
  if (rest.rfind(scheme, 0) == 0) rest = rest.substr(scheme.size());
  const auto colon = rest.rfind(':');
  if (rest.empty() || colon == 0)
    throw Error::at("command line", 0, flag, "no host in '" + url + "'");
  if (colon == std::string::npos) {
    options.host = rest;
    return;
  }
  options.host = rest.substr(0, colon);
  const std::string port = rest.substr(colon + 1);
  try {
    std::size_t used = 0;
    const int p = std::stoi(port, &used);
    if (used != port.size() || p <= 0 || p > 65535) throw std::invalid_argument("range");
    options.port = p;
  } catch (const std::exception&) {
    throw Error::at("command line", 0, flag, "bad port '" + port + "' in '" + url + "'");
  }
}

std::int64_t wall_clock_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

struct MqttClient::Impl {
  MqttOptions opt;
  mosquitto* mosq = nullptr;
  Handler handler;
  std::function<void()> connected_hook;
  std::vector<std::pair<std::string, int>> subscriptions;

  mutable std::mutex mutex;  // outbox, stats, state
  mutable std::condition_variable cv;
  std::deque<Pending> outbox;
  MqttStats stats;
  bool is_connected = false;
  std::size_t subacks_pending = 0;  // on this connection: wait_connected waits for them
  int connack = -1;
  bool started = false;
  bool stopped = false;

  // Caller holds `mutex`. Sends every entry not in flight on this connection.
  void flush_locked() {
    for (Pending& p : outbox) {
      if (p.mid != -1) continue;
      int mid = 0;
      const int rc =
          mosquitto_publish_v5(mosq, &mid, p.topic.c_str(), static_cast<int>(p.payload.size()),
                               p.payload.data(), 1, p.retain, nullptr);
      if (rc != MOSQ_ERR_SUCCESS) return;  // connection lost meanwhile: the next connect retries
      p.mid = mid;
      ++stats.sent;
    }
  }

  static void on_connect(mosquitto* m, void* self, int rc, int /*flags*/,
                         const mosquitto_property* /*props*/) {
    auto* d = static_cast<Impl*>(self);
    std::unique_lock lock(d->mutex);
    d->connack = rc;
    if (rc != 0) {
      // Wrong credentials or an unauthorized client id do not get better by retrying.
      if (rc == MQTT_RC_BAD_USERNAME_OR_PASSWORD || rc == MQTT_RC_NOT_AUTHORIZED ||
          rc == MQTT_RC_BANNED || rc == CONNACK_REFUSED_BAD_USERNAME_PASSWORD ||
          rc == CONNACK_REFUSED_NOT_AUTHORIZED) {
        mosquitto_disconnect(m);
      }
      d->cv.notify_all();
      return;
    }
    d->is_connected = true;
    ++d->stats.connects;
    d->subacks_pending = 0;
    for (const auto& [pattern, qos] : d->subscriptions) {
      if (mosquitto_subscribe_v5(m, nullptr, pattern.c_str(), qos, 0, nullptr) ==
          MOSQ_ERR_SUCCESS) {
        ++d->subacks_pending;
      }
    }
    for (Pending& p : d->outbox) p.mid = -1;  // in-flight ids of the old connection are void
    d->flush_locked();
    d->cv.notify_all();
    lock.unlock();
    if (d->connected_hook) d->connected_hook();
  }

  static void on_disconnect(mosquitto*, void* self, int, const mosquitto_property*) {
    auto* d = static_cast<Impl*>(self);
    std::lock_guard lock(d->mutex);
    if (d->is_connected) ++d->stats.disconnects;
    d->is_connected = false;
    d->cv.notify_all();
  }

  static void on_publish(mosquitto*, void* self, int mid, int reason, const mosquitto_property*) {
    auto* d = static_cast<Impl*>(self);
    std::lock_guard lock(d->mutex);
    for (auto it = d->outbox.begin(); it != d->outbox.end(); ++it) {
      if (it->mid != mid) continue;
      // A refusal (ACL) is final: re-sending would be refused again.
      if (reason >= 0x80) {
        ++d->stats.refused;
      } else {
        ++d->stats.acknowledged;
      }
      d->outbox.erase(it);
      return;
    }
  }

  static void on_subscribe(mosquitto*, void* self, int, int, const int*,
                           const mosquitto_property*) {
    auto* d = static_cast<Impl*>(self);
    std::lock_guard lock(d->mutex);
    if (d->subacks_pending > 0) --d->subacks_pending;
    d->cv.notify_all();
  }

  static void on_message(mosquitto*, void* self, const mosquitto_message* msg,
                         const mosquitto_property*) {
    auto* d = static_cast<Impl*>(self);
    {
      std::lock_guard lock(d->mutex);
      ++d->stats.received;
    }
    if (d->handler && msg->topic) {
      d->handler(msg->topic,
                 std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(msg->payload),
                                               static_cast<std::size_t>(msg->payloadlen)));
    }
  }
};

MqttClient::MqttClient(MqttOptions options) : impl_(std::make_unique<Impl>()) {
  init_library();
  impl_->opt = std::move(options);
  const MqttOptions& o = impl_->opt;
  impl_->mosq = mosquitto_new(o.client_id.empty() ? nullptr : o.client_id.c_str(), o.clean_start,
                              impl_.get());
  if (!impl_->mosq) throw Error("mosquitto_new failed for client '" + o.client_id + "'");
  mosquitto_int_option(impl_->mosq, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V5);
  // Small telemetry packets must not wait for Nagle + delayed ACK (~40 ms each way).
  mosquitto_int_option(impl_->mosq, MOSQ_OPT_TCP_NODELAY, 1);
  const std::string user = o.username.empty() ? o.client_id : o.username;
  if (!user.empty()) {
    mosquitto_username_pw_set(impl_->mosq, user.c_str(),
                              o.password.empty() ? nullptr : o.password.c_str());
  }
  if (!o.will_topic.empty()) {
    mosquitto_will_set_v5(impl_->mosq, o.will_topic.c_str(),
                          static_cast<int>(o.will_payload.size()), o.will_payload.data(), 1,
                          o.will_retain, nullptr);
  }
  mosquitto_reconnect_delay_set(impl_->mosq, o.reconnect_min_s, o.reconnect_max_s, true);
  mosquitto_connect_v5_callback_set(impl_->mosq, &Impl::on_connect);
  mosquitto_disconnect_v5_callback_set(impl_->mosq, &Impl::on_disconnect);
  mosquitto_publish_v5_callback_set(impl_->mosq, &Impl::on_publish);
  mosquitto_message_v5_callback_set(impl_->mosq, &Impl::on_message);
  mosquitto_subscribe_v5_callback_set(impl_->mosq, &Impl::on_subscribe);
}

MqttClient::~MqttClient() {
  stop(false);
  mosquitto_destroy(impl_->mosq);
}

void MqttClient::on_message(Handler handler) { impl_->handler = std::move(handler); }

void MqttClient::on_connected(std::function<void()> hook) {
  impl_->connected_hook = std::move(hook);
}

void MqttClient::subscribe(const std::string& pattern, int qos) {
  std::lock_guard lock(impl_->mutex);
  impl_->subscriptions.emplace_back(pattern, qos);
  if (impl_->is_connected && mosquitto_subscribe_v5(impl_->mosq, nullptr, pattern.c_str(), qos, 0,
                                                    nullptr) == MOSQ_ERR_SUCCESS) {
    ++impl_->subacks_pending;
  }
}

void MqttClient::start() {
  if (impl_->started) return;
  impl_->started = true;
  const MqttOptions& o = impl_->opt;
  // A refused TCP connect is not fatal: the loop thread keeps retrying with back-off. Bad
  // arguments (libmosquitto wants keepalive >= 5 s) are.
  int rc = mosquitto_connect_async(impl_->mosq, o.host.c_str(), o.port, o.keepalive_s);
  if (rc == MOSQ_ERR_INVAL) {
    throw Error("MQTT connect to " + o.host + ":" + std::to_string(o.port) +
                ": invalid arguments (keepalive must be >= 5 s)");
  }
  rc = mosquitto_loop_start(impl_->mosq);
  if (rc != MOSQ_ERR_SUCCESS) {
    throw Error(std::string("mosquitto_loop_start: ") + mosquitto_strerror(rc));
  }
}

bool MqttClient::wait_connected(std::chrono::milliseconds timeout) const {
  std::unique_lock lock(impl_->mutex);
  const auto ready = [&] { return impl_->is_connected && impl_->subacks_pending == 0; };
  return impl_->cv.wait_for(lock, timeout, [&] {
    return ready() || (impl_->connack > 0 && !impl_->is_connected);
  }) && ready();
}

bool MqttClient::connected() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->is_connected;
}

int MqttClient::connack_code() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->connack;
}

bool MqttClient::publish(const std::string& topic, std::vector<std::uint8_t> payload, int qos,
                         bool retain) {
  std::lock_guard lock(impl_->mutex);
  if (qos == 0) {
    if (!impl_->is_connected) {
      ++impl_->stats.dropped_offline;
      return false;
    }
    const int rc =
        mosquitto_publish_v5(impl_->mosq, nullptr, topic.c_str(), static_cast<int>(payload.size()),
                             payload.data(), 0, retain, nullptr);
    if (rc != MOSQ_ERR_SUCCESS) {
      ++impl_->stats.dropped_offline;
      return false;
    }
    ++impl_->stats.sent;
    return true;
  }
  bool kept = true;
  if (impl_->outbox.size() >= impl_->opt.outbox_limit) {
    impl_->outbox.pop_front();
    ++impl_->stats.outbox_overflow;
    kept = impl_->opt.outbox_limit > 0;
    if (!kept) return false;
  }
  impl_->outbox.push_back(Pending{topic, std::move(payload), retain, -1});
  if (impl_->is_connected) impl_->flush_locked();
  return kept;
}

std::size_t MqttClient::outbox_size() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->outbox.size();
}

MqttStats MqttClient::stats() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

void MqttClient::stop(bool with_will) {
  if (!impl_->started || impl_->stopped) return;
  impl_->stopped = true;
  mosquitto_disconnect_v5(impl_->mosq, with_will ? MQTT_RC_DISCONNECT_WITH_WILL_MSG : 0, nullptr);
  mosquitto_loop_stop(impl_->mosq, false);
}

}  // namespace kestrel::comm
