// station: the StampScan command-line program. Every command registers itself from the table in
// commands.cpp; main only parses and runs the one that was asked for.
#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/station/commands.hpp"

#include <cstdio>
#include <exception>
#include <vector>

int main(int argc, char** argv) {
  // Ctrl-C or a kill during any command leaves no temporary output files behind.
  stampscan::fitting::removeTemporariesOnSignals();
  CLI::App app{"StampScan: sheet-metal forming inspection: scan, fit, strain map"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "station 0.1.0");
  std::vector<std::pair<CLI::App*, stampscan::station::CommandRunner>> commands;
  for (const stampscan::station::CommandEntry& entry : stampscan::station::commandTable()) {
    stampscan::station::CommandRunner run = entry.add(app);
    commands.emplace_back(app.get_subcommand(entry.name), std::move(run));
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    for (const auto& [command, run] : commands)
      if (command->parsed()) return run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "station: error: %s\n", e.what());
    return 1;
  }
  return 2;
}
