// `kestrel station`: the ground station in a terminal: lists the agents it hears with state,
// pose rate, round trip and link health, and sends commands. With --http PORT it also serves the
// browser page (web/) on 127.0.0.1, which talks to the broker's WebSocket listener itself.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <thread>

#include "apps/commands.hpp"
#include "comm/http_server.hpp"
#include "comm/station_link.hpp"
#include "core/error.hpp"

namespace {

struct StationFlags {
  std::string broker = "mqtt://127.0.0.1:1883";
  std::string user = "station";
  std::string password;
  std::vector<std::string> commands;  // AGENT:KIND[:ARGS]
  double duration = 10.0;
  double period = 1.0;
  int http_port = -1;  // -1: no page
  int ws_port = 9001;
  std::string web_dir;
};

// web/ next to the build folder (build/kestrel -> web/), else ./web.
std::string find_web_dir() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    for (fs::path d = exe.parent_path(); !d.empty() && d != d.root_path(); d = d.parent_path()) {
      if (fs::exists(d / "web" / "index.html")) return (d / "web").string();
    }
  }
  return "web";
}

kestrel::comm::CommandMsg parse_command(const std::string& spec, std::string& agent) {
  using kestrel::comm::CommandKind;
  const auto fail = [&](const std::string& why) {
    return kestrel::Error::at("command line", 0, "--command", "'" + spec + "': " + why);
  };
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (;;) {
    const auto colon = spec.find(':', start);
    parts.push_back(spec.substr(start, colon - start));
    if (colon == std::string::npos) break;
    start = colon + 1;
  }
  if (parts.size() < 2) throw fail("expected AGENT:KIND[:ARGS]");
  agent = parts[0];
  kestrel::comm::CommandMsg c;
  const std::string& kind = parts[1];
  auto num = [&](std::size_t i) {
    try {
      return std::stod(parts.at(i));
    } catch (const std::exception&) {
      throw fail("argument " + std::to_string(i - 1) + " is not a number");
    }
  };
  if (kind == "pause") {
    c.kind = CommandKind::kPause;
  } else if (kind == "resume") {
    c.kind = CommandKind::kResume;
  } else if (kind == "home") {
    c.kind = CommandKind::kReturnHome;
  } else if (kind == "goal") {
    c.kind = CommandKind::kGoal;
    c.goal = {num(2), num(3), parts.size() > 4 ? num(4) : 0.0};
  } else if (kind == "teleop") {
    c.kind = CommandKind::kTeleop;
    c.v = num(2);
    c.w = parts.size() > 3 ? num(3) : 0.0;
  } else if (kind == "save_map") {
    c.kind = CommandKind::kSaveMap;
    if (parts.size() < 3) throw fail("save_map needs a folder");
    c.path = spec.substr(agent.size() + kind.size() + 2);
  } else {
    throw fail("unknown command '" + kind + "' (pause, resume, home, goal, teleop, save_map)");
  }
  return c;
}

void setup_station(CLI::App& app) {
  auto flags = std::make_shared<StationFlags>();
  auto* cmd = app.add_subcommand("station", "Watch agents over MQTT and send them commands");
  cmd->add_option("--broker", flags->broker, "mqtt://HOST:PORT")->capture_default_str();
  cmd->add_option("--user", flags->user, "broker user name")->capture_default_str();
  cmd->add_option("--password", flags->password, "broker password (or $KESTREL_MQTT_PASSWORD)");
  cmd->add_option("--command", flags->commands,
                  "AGENT:pause | AGENT:resume | AGENT:home | AGENT:goal:X:Y[:YAW] | "
                  "AGENT:teleop:V[:W] | AGENT:save_map:DIR (repeatable; sent once the agent is "
                  "heard)");
  cmd->add_option("--duration", flags->duration, "seconds to watch (0: until interrupted)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--http", flags->http_port,
                  "serve the browser station on http://127.0.0.1:PORT (0: a free port)")
      ->check(CLI::Range(0, 65535));
  cmd->add_option("--ws-port", flags->ws_port, "the broker's WebSocket port, for the page")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  cmd->add_option("--web", flags->web_dir, "folder with the page (default: the repository's web/)");
  cmd->callback([flags] {
    kestrel::comm::StationLinkOptions so;
    kestrel::comm::parse_broker_url(flags->broker, "--broker", so.mqtt);
    so.mqtt.username = flags->user;
    so.mqtt.client_id = flags->user;
    so.mqtt.password = flags->password;
    if (so.mqtt.password.empty()) {
      if (const char* env = std::getenv("KESTREL_MQTT_PASSWORD")) so.mqtt.password = env;
    }
    so.ping_period = std::chrono::milliseconds(500);
    std::vector<std::pair<std::string, kestrel::comm::CommandMsg>> todo;
    for (const auto& spec : flags->commands) {
      std::string agent;
      auto c = parse_command(spec, agent);
      todo.emplace_back(agent, c);
    }
    std::unique_ptr<kestrel::comm::HttpServer> http;
    if (flags->http_port >= 0) {
      const std::string web = flags->web_dir.empty() ? find_web_dir() : flags->web_dir;
      if (!std::filesystem::exists(web + "/index.html")) {
        throw kestrel::Error::at(web, 0, "--web", "no index.html (the page lives in web/)");
      }
      if (!std::filesystem::exists(web + "/node_modules/mqtt/dist/mqtt.min.js")) {
        throw kestrel::Error::at(
            web, 0, "--web", "node_modules/mqtt missing: run scripts/setup (npm ci --prefix web)");
      }
      http = std::make_unique<kestrel::comm::HttpServer>(web, flags->http_port);
      // The page connects as the station user; this is served on loopback only.
      nlohmann::json config = {
          {"broker_ws", "ws://" + so.mqtt.host + ":" + std::to_string(flags->ws_port)},
          {"username", so.mqtt.username},
          {"password", so.mqtt.password},
          {"client_id", so.mqtt.username + "-web-" + std::to_string(getpid())}};
      const std::string body = config.dump();
      http->route("/config.json", [body] {
        return kestrel::comm::HttpResponse{200, "application/json", body};
      });
      http->start();
      std::printf("station page: http://127.0.0.1:%d/ (serving %s)\n", http->port(), web.c_str());
      std::fflush(stdout);
    }
    kestrel::comm::StationLink station(so);
    station.start();
    if (!station.wait_connected(std::chrono::seconds(5))) {
      throw kestrel::Error("kestrel station: cannot connect to " + flags->broker + " (CONNACK " +
                           std::to_string(station.client().connack_code()) + ")");
    }
    std::map<std::string, std::string> sent;  // command id -> agent
    std::map<std::string, std::uint64_t> last_poses;
    const auto t0 = std::chrono::steady_clock::now();
    while (flags->duration <= 0 ||
           std::chrono::steady_clock::now() - t0 < std::chrono::duration<double>(flags->duration)) {
      std::this_thread::sleep_for(std::chrono::duration<double>(flags->period));
      const auto agents = station.agents();
      for (auto it = todo.begin(); it != todo.end();) {
        if (!agents.count(it->first)) {
          ++it;
          continue;
        }
        if (auto id = station.send_command(it->first, it->second)) sent[*id] = it->first;
        it = todo.erase(it);
      }
      std::printf("%-12s %-5s %-13s %8s %9s %9s %10s %7s\n", "agent", "role", "state", "pose Hz",
                  "rtt ms", "missed", "objects", "path");
      for (const auto& [id, a] : agents) {
        const double hz = static_cast<double>(a.poses - last_poses[id]) / flags->period;
        last_poses[id] = a.poses;
        std::printf("%-12s %-5s %-13s %8.1f %9.2f %9llu %10zu %7zu\n", id.c_str(),
                    a.status.role.c_str(), a.have_status ? a.status.state.c_str() : "?", hz,
                    a.clock.empty() ? -1.0 : a.clock.rtt_percentile_ns(0.5) * 1e-6,
                    static_cast<unsigned long long>(a.poses_missed), a.objects.size(),
                    a.path ? a.path->points.size() : 0);
      }
      for (auto it = sent.begin(); it != sent.end();) {
        if (auto ack = station.ack(it->first)) {
          std::printf("  ack %s from %s: %s %s\n", it->first.c_str(), it->second.c_str(),
                      kestrel::comm::to_string(ack->result), ack->detail.c_str());
          it = sent.erase(it);
        } else {
          ++it;
        }
      }
      std::fflush(stdout);
    }
    for (const auto& [agent, c] : todo) {
      std::printf("  not sent: %s to '%s' (never heard from that agent)\n",
                  kestrel::comm::to_string(c.kind), agent.c_str());
    }
    for (const auto& [id, agent] : sent) {
      std::printf("  no acknowledgement yet: %s to '%s'\n", id.c_str(), agent.c_str());
    }
    const auto c = station.counts();
    std::printf("station: %llu commands sent (%llu re-sent), %llu acks, %llu messages rejected\n",
                static_cast<unsigned long long>(c.commands_sent),
                static_cast<unsigned long long>(c.command_resends),
                static_cast<unsigned long long>(c.acks),
                static_cast<unsigned long long>(c.decode.rejected()));
  });
}

}  // namespace

KESTREL_COMMAND(71, setup_station);
