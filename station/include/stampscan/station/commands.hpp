// Subcommands of the station program. Each registers itself on the CLI app and returns what runs it;
// commandTable() lists them all, in the order `station --help` shows them. A command is a thin
// caller of the libraries below (acquisition, registration, fitting): no workflow lives here.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <span>

namespace stampscan::station {

// Returns the process exit code.
using CommandRunner = std::function<int()>;

struct CommandEntry {
  const char* name;
  CommandRunner (*add)(CLI::App& app);
};
std::span<const CommandEntry> commandTable();

CommandRunner addScanCommand(CLI::App& app);
CommandRunner addPlanCommand(CLI::App& app);
CommandRunner addFitCommand(CLI::App& app);
CommandRunner addSampleCommand(CLI::App& app);
CommandRunner addCellCommand(CLI::App& app);
CommandRunner addDemoCommand(CLI::App& app);
CommandRunner addSimCommand(CLI::App& app);
CommandRunner addProcessCommand(CLI::App& app);
CommandRunner addDevicesCommand(CLI::App& app);
CommandRunner addTraceCommand(CLI::App& app);
CommandRunner addReportCommand(CLI::App& app);
CommandRunner addHistoryCommand(CLI::App& app);
CommandRunner addTrendCommand(CLI::App& app);
CommandRunner addCalibrateCommand(CLI::App& app);
CommandRunner addVerifyCommand(CLI::App& app);
CommandRunner addCalibrationCommand(CLI::App& app);
// In the station program itself, above the panel's library (station/hmi).
CommandRunner addHmiCommand(CLI::App& app);
// `sim serve`, under the `sim` command.
CommandRunner addServeSubcommand(CLI::App* sim);
// `sim part`, under the `sim` command.
CommandRunner addSimPartSubcommand(CLI::App* sim);

}  // namespace stampscan::station
