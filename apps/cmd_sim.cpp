// `kestrel sim`: render a named (or YAML-file) scenario into a Kestrel sequence.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

#include "apps/commands.hpp"
#include "core/error.hpp"
#include "sim/builtin_scenarios.hpp"
#include "sim/sequence_recorder.hpp"

namespace {

struct SimOptions {
  std::string scenario;
  std::string out;
  long long seed = -1;
  double duration = -1.0;
  bool no_movers = false;
};

// A bar redrawn in place on a terminal; a line every 10 % otherwise (logs, CI).
void show_progress(int done, int total, bool tty,
                   const std::chrono::steady_clock::time_point& start) {
  const double secs =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double fps = secs > 0 ? done / secs : 0.0;
  if (tty) {
    constexpr int kWidth = 40;
    const int filled = total > 0 ? done * kWidth / total : kWidth;
    std::printf("\r[%s%s] %d/%d frames  %.1f fps",
                std::string(static_cast<std::size_t>(filled), '#').c_str(),
                std::string(static_cast<std::size_t>(kWidth - filled), '.').c_str(), done, total,
                fps);
    if (done == total) std::printf("\n");
    std::fflush(stdout);
  } else if (done == total || (done * 10 / total) != ((done - 1) * 10 / total)) {
    std::printf("rendered %d/%d frames (%.1f fps)\n", done, total, fps);
    std::fflush(stdout);
  }
}

void setup_sim(CLI::App& app) {
  auto opt = std::make_shared<SimOptions>();
  std::string names;
  for (const auto& n : kestrel::sim::builtin_scenario_names())
    names += (names.empty() ? "" : ", ") + n;
  auto* cmd = app.add_subcommand(
      "sim", "Render a synthetic dynamic RGB-D + IMU sequence with ground truth");
  cmd->add_option("--scenario", opt->scenario,
                  "built-in name (" + names + ") or a scenario YAML file")
      ->required();
  cmd->add_option("--out", opt->out, "output folder (a Kestrel sequence)")->required();
  cmd->add_option("--seed", opt->seed, "random seed (default: the scenario's)");
  cmd->add_option("--duration", opt->duration, "seconds to render (default: the scenario's)");
  cmd->add_flag("--no-movers", opt->no_movers, "the same world and path with the movers taken out");
  cmd->callback([opt] {
    try {
      kestrel::sim::ScenarioOverrides ov;
      ov.seed = opt->seed;
      ov.duration = opt->duration;
      ov.no_movers = opt->no_movers;
      kestrel::sim::Simulator sim(kestrel::sim::load_scenario(opt->scenario, ov));
      const bool tty = isatty(fileno(stdout)) != 0;
      std::printf("scenario %s: %d frames (%.1f s), %zu movers, %zu objects -> %s\n",
                  sim.scenario().name.c_str(), sim.frame_count(), sim.duration(),
                  sim.world().movers().size(), sim.world().objects().size(), opt->out.c_str());
      const auto start = std::chrono::steady_clock::now();
      const auto stats = kestrel::sim::record_sequence(
          sim, opt->out, [&](int done, int total) { show_progress(done, total, tty, start); });
      std::printf(
          "wrote %d frames (%d dropped), %d IMU samples; render %.1f fps; movers cover >= 25%% of "
          "the "
          "image in %.0f%% of frames\n",
          stats.written, stats.frames - stats.written, stats.imu_samples,
          stats.render_seconds > 0 ? stats.frames / stats.render_seconds : 0.0,
          100.0 * stats.frames_with_quarter_movers / std::max(1, stats.frames));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "kestrel sim: %s\n", e.what());
      kestrel::apps::exit_code() = 1;
    }
  });
}

}  // namespace

KESTREL_COMMAND(20, setup_sim);
