#pragma once
// A real mosquitto on free loopback ports, started through scripts/mosquitto/start_broker.sh with
// its password file and ACL: what the integration tests and the telemetry benchmarks talk to.
// RAII: the destructor always kills the broker and removes its folder, so a failure leaves no
// process behind. Throws kestrel::Error when mosquitto is missing or does not come up.
#include <string>
#include <utility>
#include <vector>

namespace kestrel::comm {

class LocalBroker {
 public:
  // users: {name, password}; "station" is the one allowed to publish commands.
  explicit LocalBroker(std::vector<std::pair<std::string, std::string>> users);
  ~LocalBroker();
  LocalBroker(const LocalBroker&) = delete;
  LocalBroker& operator=(const LocalBroker&) = delete;

  int port() const { return port_; }
  int ws_port() const { return ws_port_; }
  const std::string& dir() const { return dir_; }
  bool running() const { return pid_ > 0; }
  int pid() const { return pid_; }  // the mosquitto process (the script execs it)

  // Stops the broker with a signal (SIGKILL: a crash; SIGTERM: a clean shutdown).
  void stop(int signal);
  // Starts it again on the same ports with the same folder (persistence included).
  void start();
  std::string log() const;

 private:
  std::vector<std::pair<std::string, std::string>> users_;
  std::string dir_;
  int port_ = 0;
  int ws_port_ = 0;
  int pid_ = -1;
};

int free_loopback_port();

}  // namespace kestrel::comm
