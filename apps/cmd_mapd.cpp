// `kestrel mapd`: the team map server (comm/mapd.hpp does the work): merges the agents' object
// databases into one map in the team frame and publishes it on kestrel/v1/team/objects.
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <thread>

#include "apps/commands.hpp"
#include "comm/mapd.hpp"
#include "core/error.hpp"
#include "io/kestrel_sequence.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

struct MapdFlags {
  std::string broker = "mqtt://127.0.0.1:1883";
  std::string user = "mapd";
  std::string password;
  std::string agents;
  std::vector<std::string> starts;
  double duration = 0.0;
  double period = 1.0;
  std::string out;
};

void print_map(const kestrel::comm::TeamMapResult& r) {
  for (const auto& [agent, f] : r.frames) {
    std::printf(
        "  frame %-12s %s x %.3f y %.3f z %.3f yaw %.2f deg (prior %.3f %.3f %.3f %.2f), "
        "%d matched\n",
        agent.c_str(), f.reference ? "reference" : "aligned  ", f.T_team_agent.t[0],
        f.T_team_agent.t[1], f.T_team_agent.t[2], f.T_team_agent.yaw * 180 / M_PI, f.prior.t[0],
        f.prior.t[1], f.prior.t[2], f.prior.yaw * 180 / M_PI, f.matched);
  }
  for (const auto& o : r.objects) {
    std::string who;
    for (const auto& a : o.agents) who += (who.empty() ? "" : ",") + a;
    std::printf("  object %3u %-14s (%.2f, %.2f, %.2f) size %.2fx%.2fx%.2f, %u obs, seen by %s\n",
                o.id, o.label.c_str(), o.center[0], o.center[1], o.center[2], o.size[0], o.size[1],
                o.size[2], o.observations, who.c_str());
  }
}

void setup_mapd(CLI::App& app) {
  auto flags = std::make_shared<MapdFlags>();
  auto* cmd = app.add_subcommand(
      "mapd", "Team map: merge every agent's objects into one map and publish it");
  cmd->add_option("--broker", flags->broker, "mqtt://HOST:PORT")->capture_default_str();
  cmd->add_option("--user", flags->user, "broker user (the ACL lets it write kestrel/v1/team/#)")
      ->capture_default_str();
  cmd->add_option("--password", flags->password, "broker password (or $KESTREL_MQTT_PASSWORD)");
  cmd->add_option("--agents", flags->agents,
                  "comma-separated team; objects from anyone else are rejected (default: any)");
  cmd->add_option("--start", flags->starts,
                  "NAME:x,y,z,yaw_deg  an agent's start pose in the team frame (repeatable); "
                  "the first is the reference")
      ->take_all();
  cmd->add_option("--duration", flags->duration, "seconds to run (0: until interrupted)")
      ->check(CLI::Range(0.0, 1e7));
  cmd->add_option("--period", flags->period, "seconds between team map snapshots at most")
      ->check(CLI::Range(0.05, 3600.0))
      ->capture_default_str();
  cmd->add_option("--out", flags->out, "write the team map here at the end (objects.json)");
  cmd->callback([flags] {
    kestrel::comm::MapdOptions opt;
    kestrel::comm::parse_broker_url(flags->broker, "--broker", opt.mqtt);
    opt.mqtt.username = flags->user;
    opt.mqtt.password = flags->password;
    if (opt.mqtt.password.empty()) {
      if (const char* env = std::getenv("KESTREL_MQTT_PASSWORD")) opt.mqtt.password = env;
    }
    std::stringstream in(flags->agents);
    for (std::string a; std::getline(in, a, ',');)
      if (!a.empty()) opt.agents.push_back(a);
    for (const auto& s : flags->starts)
      opt.starts.push_back(kestrel::comm::parse_start_pose(s, "--start"));
    opt.publish_period_s = flags->period;

    kestrel::comm::Mapd mapd(opt);
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    mapd.start();
    std::printf("kestrel mapd -> %s:%d, team: %s\n", opt.mqtt.host.c_str(), opt.mqtt.port,
                flags->agents.empty() ? "any agent" : flags->agents.c_str());
    std::fflush(stdout);
    if (!mapd.wait_connected(std::chrono::seconds(10))) {
      std::fprintf(stderr, "kestrel mapd: broker not reachable yet (connack %d); retrying\n",
                   mapd.client().connack_code());
    }
    const auto t0 = std::chrono::steady_clock::now();
    std::size_t shown = 0;
    while (!g_stop &&
           (flags->duration <= 0 || std::chrono::steady_clock::now() - t0 <
                                        std::chrono::duration<double>(flags->duration))) {
      if (mapd.spin_once()) {
        const auto r = mapd.last();
        if (r.objects.size() != shown) {
          shown = r.objects.size();
          std::printf("team map: %zu objects from %zu agents\n", shown, r.frames.size());
          std::fflush(stdout);
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    mapd.spin_once(true);
    // Let the last snapshot reach the broker before disconnecting.
    for (int i = 0; i < 100 && mapd.client().outbox_size() > 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const auto r = mapd.last();
    const auto c = mapd.counts();
    std::printf(
        "mapd: %zu team objects (%d merged across agents), %llu objects messages applied, "
        "%llu snapshots published; rejected %llu: %llu unknown agent, %llu wrong kind, "
        "%llu oversized, %llu malformed, %llu unknown version, %llu unknown kind, %llu bad field\n",
        r.objects.size(), r.merged, static_cast<unsigned long long>(c.applied),
        static_cast<unsigned long long>(c.published), static_cast<unsigned long long>(c.rejected()),
        static_cast<unsigned long long>(c.unknown_agent),
        static_cast<unsigned long long>(c.wrong_kind),
        static_cast<unsigned long long>(c.decode.oversized),
        static_cast<unsigned long long>(c.decode.malformed),
        static_cast<unsigned long long>(c.decode.unknown_version),
        static_cast<unsigned long long>(c.decode.unknown_kind),
        static_cast<unsigned long long>(c.decode.bad_field));
    print_map(r);
    if (!flags->out.empty()) {
      std::filesystem::create_directories(flags->out);
      std::vector<kestrel::io::SequenceObject> objs;
      for (const auto& o : r.objects) {
        kestrel::io::SequenceObject s;
        s.id = static_cast<int>(o.id);
        s.label = o.label;
        s.center = kestrel::Vec3(o.center[0], o.center[1], o.center[2]);
        s.size = kestrel::Vec3(o.size[0], o.size[1], o.size[2]);
        s.yaw = o.yaw;
        s.observations = static_cast<int>(o.observations);
        objs.push_back(s);
      }
      kestrel::io::write_objects_json(flags->out + "/objects.json", objs);
      std::printf("wrote %s/objects.json\n", flags->out.c_str());
    }
  });
}

}  // namespace

KESTREL_COMMAND(75, setup_mapd);
