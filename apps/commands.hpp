#pragma once
// Each `kestrel` subcommand lives in its own apps/cmd_*.cpp and registers itself with
// KESTREL_COMMAND(order, function); main() adds them to the CLI in `order`.
// apps/ only parses flags, wires library parts together and prints; no algorithm lives here.
#include <CLI/App.hpp>

namespace kestrel::apps {

using CommandSetup = void (*)(CLI::App& app);

bool register_command(int order, CommandSetup setup);
void add_registered_commands(CLI::App& app);

// Set by a subcommand's callback; main() returns it.
int& exit_code();

}  // namespace kestrel::apps

#define KESTREL_COMMAND(order, setup)                    \
  static const bool kestrel_command_registered_##setup = \
      ::kestrel::apps::register_command(order, setup)
