// Subcommands of the station program. Each registers itself on the CLI app and returns the exit code.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace stampscan::station {

// Each returns a callable run after parsing, which returns the process exit code.
using CommandRunner = std::function<int()>;

CommandRunner addFitCommand(CLI::App& app);
CommandRunner addSampleCommand(CLI::App& app);
CommandRunner addDemoCommand(CLI::App& app);
CommandRunner addSimCommand(CLI::App& app);
CommandRunner addProcessCommand(CLI::App& app);
CommandRunner addDevicesCommand(CLI::App& app);
// `sim serve`, under the `sim` command.
CommandRunner addServeSubcommand(CLI::App* sim);
CommandRunner addTraceCommand(CLI::App& app);

}  // namespace stampscan::station
