#pragma once
// A small blocking HTTP/1.1 server for the station page: serves the files under one folder and a
// few generated routes (e.g. /config.json) on 127.0.0.1 only. One connection at a time, GET and
// HEAD only, Connection: close — enough for one operator's browser on loopback, not a web server.
#include <atomic>
#include <functional>
#include <map>
#include <string>
#include <thread>

namespace kestrel::comm {

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
};

class HttpServer {
 public:
  using Route = std::function<HttpResponse()>;

  // root: the folder served; port 0 picks a free one (see port()).
  HttpServer(std::string root, int port);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  // A generated response for an exact path (checked before files). Call before start().
  void route(const std::string& path, Route fn);
  // Binds 127.0.0.1:port and serves on a thread; throws kestrel::Error when it cannot bind.
  void start();
  void stop();
  int port() const { return port_; }
  std::uint64_t requests() const { return requests_.load(); }

  // Maps a request target to a file under root; empty when the target is malformed or escapes
  // the root ("..", hidden components, NUL). Exposed for tests.
  static std::string resolve(const std::string& root, const std::string& target);
  static const char* mime_type(const std::string& path);

 private:
  void serve(std::stop_token stop);
  void handle(int fd);

  std::string root_;
  int port_;
  int listen_fd_ = -1;
  std::map<std::string, Route> routes_;
  std::atomic<std::uint64_t> requests_{0};
  std::jthread thread_;
};

}  // namespace kestrel::comm
