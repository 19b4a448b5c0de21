// The station page's HTTP server (comm/http_server.hpp): file mapping that cannot leave the web
// folder, and real requests over loopback. The browser end-to-end test is tests/web/.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "comm/http_server.hpp"

namespace kestrel::comm {
namespace {

std::string request(int port, const std::string& text) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    close(fd);
    return "connect failed";
  }
  send(fd, text.data(), text.size(), MSG_NOSIGNAL);
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = recv(fd, buf, sizeof buf, 0)) > 0;)
    out.append(buf, static_cast<std::size_t>(n));
  close(fd);
  return out;
}

std::string get(int port, const std::string& target) {
  return request(port, "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
}

TEST(HttpServer, ResolveStaysInsideTheRoot) {
  EXPECT_EQ(HttpServer::resolve("/w", "/"), "/w/index.html");
  EXPECT_EQ(HttpServer::resolve("/w", "/station.js?v=2"), "/w/station.js");
  EXPECT_EQ(HttpServer::resolve("/w", "/node_modules/mqtt/dist/mqtt.min.js"),
            "/w/node_modules/mqtt/dist/mqtt.min.js");
  EXPECT_EQ(HttpServer::resolve("/w", "/a%20b.css"), "/w/a b.css");
  for (const char* bad : {"", "index.html", "/../etc/passwd", "/%2e%2e/etc/passwd", "/a/../../x",
                          "/.git/config", "/a//b", "/x%00.js", "/%zz", "/a%2", "/a\\..\\b"}) {
    EXPECT_EQ(HttpServer::resolve("/w", bad), "") << bad;
  }
}

TEST(HttpServer, ServesFilesRoutesAndErrors) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("kestrel-http-test-" + std::to_string(getpid()));
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "index.html") << "<p>hello</p>";
  std::ofstream(dir / "sub" / "app.js") << "let x = 1;";
  std::ofstream(dir.parent_path() / ("kestrel-http-secret-" + std::to_string(getpid()))) << "no";

  HttpServer server(dir.string(), 0);
  server.route("/config.json", [] { return HttpResponse{200, "application/json", "{\"a\":1}"}; });
  server.start();
  ASSERT_GT(server.port(), 0);

  const std::string index = get(server.port(), "/");
  EXPECT_EQ(index.rfind("HTTP/1.1 200 OK\r\n", 0), 0u) << index;
  EXPECT_NE(index.find("Content-Type: text/html"), std::string::npos);
  EXPECT_NE(index.find("Content-Length: 12\r\n"), std::string::npos);
  EXPECT_EQ(index.substr(index.size() - 12), "<p>hello</p>");

  const std::string js = get(server.port(), "/sub/app.js");
  EXPECT_NE(js.find("text/javascript"), std::string::npos);
  EXPECT_NE(js.find("let x = 1;"), std::string::npos);

  const std::string config = get(server.port(), "/config.json?x=1");
  EXPECT_NE(config.find("application/json"), std::string::npos);
  EXPECT_NE(config.find("{\"a\":1}"), std::string::npos);

  EXPECT_EQ(get(server.port(), "/missing.js").rfind("HTTP/1.1 404", 0), 0u);
  EXPECT_EQ(get(server.port(), "/sub").rfind("HTTP/1.1 404", 0), 0u);  // a folder
  const std::string escape =
      get(server.port(), "/%2e%2e/kestrel-http-secret-" + std::to_string(getpid()));
  EXPECT_EQ(escape.rfind("HTTP/1.1 404", 0), 0u) << escape;
  EXPECT_EQ(request(server.port(), "POST / HTTP/1.1\r\n\r\n").rfind("HTTP/1.1 405", 0), 0u);
  EXPECT_EQ(request(server.port(), "nonsense\r\n\r\n").rfind("HTTP/1.1 400", 0), 0u);
  const std::string head = request(server.port(), "HEAD / HTTP/1.1\r\n\r\n");
  EXPECT_NE(head.find("Content-Length: 12\r\n"), std::string::npos);
  EXPECT_EQ(head.find("hello"), std::string::npos);  // no body for HEAD
  EXPECT_EQ(server.requests(), 9u);

  server.stop();
  EXPECT_EQ(get(server.port(), "/"), "connect failed");
  fs::remove_all(dir);
  fs::remove(dir.parent_path() / ("kestrel-http-secret-" + std::to_string(getpid())));
}

}  // namespace
}  // namespace kestrel::comm
