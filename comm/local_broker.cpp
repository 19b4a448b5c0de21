#include "comm/local_broker.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include "core/error.hpp"

namespace kestrel::comm {
namespace {

bool port_open(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0;
  close(fd);
  return ok;
}

}  // namespace

int free_loopback_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = 0;  // the kernel picks a free port
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(addr);
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
      getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    close(fd);
    throw Error("no free loopback port");
  }
  close(fd);
  return ntohs(addr.sin_port);
}

LocalBroker::LocalBroker(std::vector<std::pair<std::string, std::string>> users)
    : users_(std::move(users)) {
  char tmpl[] = "/tmp/kestrel-broker-XXXXXX";
  if (!mkdtemp(tmpl)) throw Error("mkdtemp failed");
  dir_ = tmpl;
  port_ = free_loopback_port();
  ws_port_ = free_loopback_port();
  start();
}

LocalBroker::~LocalBroker() {
  stop(SIGKILL);
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
}

void LocalBroker::start() {
  if (pid_ > 0) return;
  std::vector<std::string> args = {
      "/bin/bash",   KESTREL_SOURCE_DIR "/scripts/mosquitto/start_broker.sh",
      "--dir",       dir_,
      "--port",      std::to_string(port_),
      "--ws-port",   std::to_string(ws_port_),
      "--foreground"};
  for (const auto& [name, pass] : users_) {
    args.push_back("--user");
    args.push_back(name + ":" + pass);
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid < 0) throw Error("fork failed");
  if (pid == 0) {
    execv(argv[0], argv.data());
    _exit(127);
  }
  pid_ = pid;
  for (int i = 0; i < 100; ++i) {
    if (port_open(port_)) return;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      throw Error("mosquitto exited at start:\n" + log());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  stop(SIGKILL);
  throw Error("mosquitto did not open port " + std::to_string(port_) + "\n" + log());
}

void LocalBroker::stop(int signal) {
  if (pid_ <= 0) return;
  kill(pid_, signal);
  int status = 0;
  waitpid(pid_, &status, 0);
  pid_ = -1;
}

std::string LocalBroker::log() const {
  std::ifstream in(dir_ + "/mosquitto.log");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace kestrel::comm
