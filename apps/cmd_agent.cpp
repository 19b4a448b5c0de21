// `kestrel agent`: one UAV/UGV agent replaying a source at sensor rate through the system and
// talking to the station over MQTT (comm/agent_runner.hpp does the work).
#include <unistd.h>
#include <cstdio>
#include <filesystem>

#include "apps/commands.hpp"
#include "comm/agent_runner.hpp"
#include "core/error.hpp"
#include "io/dataset.hpp"
#include "sim/scenario.hpp"
#include "sim/sequence_recorder.hpp"
#include "sim/simulator.hpp"

namespace {

struct AgentFlags {
  std::string id;
  std::string role = "ugv";
  std::string broker = "mqtt://127.0.0.1:1883";
  std::string user;
  std::string password;
  std::string source;
  double duration = 0.0;
  double linger = 0.0;
  double rate = 1.0;
  double start_time = 0.0;
  std::string detector = "none";
  std::string yolo_model = kestrel::detect::to_string(kestrel::detect::kPipelineYoloModel);
  bool fast = false;
  std::string video = "640x480";
  int video_kbps = 0;
  int video_fps = 30;
};

void setup_agent(CLI::App& app) {
  auto flags = std::make_shared<AgentFlags>();
  auto* cmd = app.add_subcommand(
      "agent", "Run one agent: replay a source, publish telemetry over MQTT, obey commands");
  cmd->add_option("--id", flags->id, "agent id (also the broker user name)")->required();
  cmd->add_option("--role", flags->role, "uav | ugv")
      ->check(CLI::IsMember({"uav", "ugv"}))
      ->capture_default_str();
  cmd->add_option("--broker", flags->broker, "mqtt://HOST:PORT")->capture_default_str();
  cmd->add_option("--user", flags->user, "broker user name (default: the id)");
  cmd->add_option("--password", flags->password, "broker password (or $KESTREL_MQTT_PASSWORD)");
  cmd->add_option("--source", flags->source, "sim:SCENARIO | kestrel:DIR | tum:DIR | euroc:DIR")
      ->required();
  cmd->add_option("--duration", flags->duration, "seconds of the source to replay (0: all)")
      ->check(CLI::Range(0.0, 36000.0));
  cmd->add_option("--start-time", flags->start_time,
                  "start this many seconds into the source (another start on the same path)")
      ->check(CLI::Range(0.0, 36000.0));
  cmd->add_option("--detector", flags->detector,
                  "yolo | oracle (the simulator's truth boxes: sim: and kestrel: sources) | none")
      ->check(CLI::IsMember({"yolo", "oracle", "none"}))
      ->capture_default_str();
  cmd->add_option("--yolo-model", flags->yolo_model,
                  "with --detector yolo: v1.1, xl (the default) or body (persons)")
      ->check(CLI::IsMember({"v1.1", "xl", "body"}))
      ->capture_default_str();
  cmd->add_option("--linger", flags->linger,
                  "seconds to stay online after the source ends (commands, pings, last frame)")
      ->check(CLI::Range(0.0, 86400.0));
  auto* fast =
      cmd->add_flag("--fast", flags->fast, "replay as fast as possible instead of at sensor rate");
  cmd->add_option("--rate", flags->rate,
                  "replay at this multiple of the sensor rate (0.5: half speed; a slow machine "
                  "or a sanitizer build keeps up with a slower replay)")
      ->check(CLI::Range(0.01, 100.0))
      ->excludes(fast);
  cmd->add_option("--video", flags->video,
                  "WebRTC video to the station page: WIDTHxHEIGHT (640x480, 1280x720) | off")
      ->capture_default_str();
  cmd->add_option("--video-kbps", flags->video_kbps,
                  "video bitrate target and ceiling, kbit/s (0: 3000 at 720p, scaled by pixels)")
      ->check(CLI::Range(0, 50000));
  cmd->add_option("--video-fps", flags->video_fps, "frame rate the encoder budgets for")
      ->check(CLI::Range(1, 120))
      ->capture_default_str();
  cmd->callback([flags] {
    namespace fs = std::filesystem;
    kestrel::comm::AgentRunOptions opt;
    opt.link.id = flags->id;
    opt.link.role = flags->role;
    kestrel::comm::parse_broker_url(flags->broker, "--broker", opt.link.mqtt);
    opt.link.mqtt.username = flags->user.empty() ? flags->id : flags->user;
    opt.link.mqtt.password = flags->password;
    if (opt.link.mqtt.password.empty()) {
      if (const char* env = std::getenv("KESTREL_MQTT_PASSWORD")) opt.link.mqtt.password = env;
    }
    opt.duration_s = flags->duration;
    opt.start_s = flags->start_time;
    opt.linger_s = flags->linger;
    opt.detector = flags->detector;
    opt.yolo_model = *kestrel::detect::parse_yolo_model(flags->yolo_model);
    opt.realtime = !flags->fast;
    opt.rate = flags->rate;
    if (flags->video != "off") {
      kestrel::comm::VideoOptions video;
      kestrel::comm::parse_video_size(flags->video, "--video", video);
      video.kbps = flags->video_kbps;
      video.fps = flags->video_fps;
      opt.video = video;
    }

    std::string spec = flags->source;
    std::string rendered;
    if (spec.rfind("sim:", 0) == 0) {
      // The simulator renders the scenario once; the agent then replays it at sensor rate.
      kestrel::sim::ScenarioOverrides over;
      if (flags->duration > 0) over.duration = flags->start_time + flags->duration;
      kestrel::sim::Simulator sim(kestrel::sim::load_scenario(spec.substr(4), over));
      rendered = (fs::temp_directory_path() /
                  ("kestrel-agent-" + flags->id + "-" + std::to_string(getpid())))
                     .string();
      std::printf("kestrel agent %s: rendering '%s' (%d frames)\n", flags->id.c_str(),
                  spec.substr(4).c_str(), sim.frame_count());
      kestrel::sim::record_sequence(sim, rendered);
      spec = "kestrel:" + rendered;
    }
    if (spec.rfind("kestrel:", 0) == 0) {
      opt.dataset_dir = spec.substr(8);
    } else if (fs::exists(fs::path(spec) / "boxes.csv")) {
      opt.dataset_dir = spec;  // a bare Kestrel sequence folder
    }
    auto source = kestrel::io::open_dataset(spec);
    std::printf("kestrel agent %s (%s) -> %s:%d: %s\n", flags->id.c_str(), flags->role.c_str(),
                opt.link.mqtt.host.c_str(), opt.link.mqtt.port, source->describe().c_str());
    std::fflush(stdout);
    const auto s = kestrel::comm::run_agent(*source, opt);
    if (!rendered.empty()) fs::remove_all(rendered);
    std::printf(
        "agent %s: %zu frames, %zu tracked, %llu poses, %llu grid messages (%llu bytes), "
        "%llu paths, %zu objects (%llu deltas, %llu snapshots), %llu commands (+%llu "
        "duplicates), %llu MQTT messages sent, %.1f s\n",
        flags->id.c_str(), s.frames, s.tracked, static_cast<unsigned long long>(s.poses_published),
        static_cast<unsigned long long>(s.grid_messages),
        static_cast<unsigned long long>(s.grid_bytes),
        static_cast<unsigned long long>(s.paths_published), s.objects,
        static_cast<unsigned long long>(s.object_messages),
        static_cast<unsigned long long>(s.object_snapshots),
        static_cast<unsigned long long>(s.link.commands_executed),
        static_cast<unsigned long long>(s.link.commands_duplicate),
        static_cast<unsigned long long>(s.mqtt.sent), s.wall_seconds);
    std::printf(
        "agent %s poses: %llu tracked, %llu interpolated, %llu extrapolated (%zu frames not fed "
        "while the tracker was busy), %.1f per second of wall time\n",
        flags->id.c_str(), static_cast<unsigned long long>(s.poses.tracked),
        static_cast<unsigned long long>(s.poses.interpolated),
        static_cast<unsigned long long>(s.poses.extrapolated), s.frames_dropped,
        s.wall_seconds > 0 ? static_cast<double>(s.poses_published) / s.wall_seconds : 0.0);
    if (s.video_on) {
      std::printf(
          "agent %s video: %llu viewers served, %llu offers, %llu answers, %llu signaling "
          "messages rejected\n",
          flags->id.c_str(), static_cast<unsigned long long>(s.video.viewers_created),
          static_cast<unsigned long long>(s.video.offers),
          static_cast<unsigned long long>(s.video.answers),
          static_cast<unsigned long long>(s.video.rejected_total()));
    }
  });
}

}  // namespace

KESTREL_COMMAND(70, setup_agent);
