// `kestrel version`: what build this is, for reports and bug reports.
#include <cstdio>

#include "apps/commands.hpp"

namespace {
void setup_version(CLI::App& app) {
  auto* cmd = app.add_subcommand("version", "Print the Kestrel version");
  cmd->callback([] { std::printf("kestrel %s\n", KESTREL_VERSION); });
}
}  // namespace

KESTREL_COMMAND(1000, setup_version);
