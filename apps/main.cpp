// kestrel — one CLI for every job: eval, sim, run, demo, bench, agent, station, mapd.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

#include "apps/commands.hpp"
#include "core/error.hpp"

int main(int argc, char** argv) {
  CLI::App app{"Kestrel: visual-inertial semantic SLAM for UAV/UGV teams in dynamic scenes"};
  app.set_version_flag("--version", std::string("kestrel ") + KESTREL_VERSION);
  app.require_subcommand(1);
  kestrel::apps::add_registered_commands(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line and exit code 2, like any Unix tool given a bad flag.
    std::fprintf(stderr, "kestrel: error: %s (see --help)\n", e.what());
    return 2;
  } catch (const kestrel::Error& e) {
    std::fprintf(stderr, "kestrel: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kestrel: unexpected error: %s\n", e.what());
    return 1;
  }
  return kestrel::apps::exit_code();
}
