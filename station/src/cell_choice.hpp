// The cell a command works on, as its options name it, and the preamble of every command that runs
// a cell (scan, calibrate, verify, devices, hmi): the cell file read, and when the cell is hosted
// here, its virtual twin built from the file and served. One piece of code, so that the commands
// take the cell alike.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/station/measuring_priority.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>
#include <string>

namespace stampscan::station {

// A cell a command runs on: its file's config, and its virtual twin when it is hosted here.
struct CommandCell {
  acquisition::CellConfig config;
  bool virtual_cell = false;              // hosted in this process
  std::unique_ptr<VirtualCellHost> host;  // once simulate() has built the twin's world
  std::optional<MeasuringPriority> priority;  // once serveToMeasure() has raised it; put back with the cell

  // The twin's world, on a hosted cell (nothing otherwise): the config's cameras become the world's.
  VirtualCellHost* simulate(const VirtualWorld& world) {
    if (virtual_cell && !host) host = std::make_unique<VirtualCellHost>(world, config);
    return host.get();
  }
  // Serves the twin (when simulated) and points the config at its devices. First thing before the
  // devices are reached: it may re-execute the program, and its digitizer must be on the bus before
  // any libusb context exists.
  void serve(bool cameras) {
    if (!host) return;
    host->start(cameras);
    config = host->config();
  }
  // serve(), then the measurement's priority (measuring_priority.hpp) for as long as this cell is
  // in use: after serving, since serving may re-execute the program, which would not put the
  // session's share back. For the commands that measure (scan, calibrate, verify, hmi).
  void serveToMeasure(bool cameras) {
    serve(cameras);
    priority.emplace(raiseMeasuringPriority());
  }
  // The priority line of the command's output (after serveToMeasure()).
  std::string priorityNote() const { return priority ? priority->describe() : "nice as started"; }
  const char* hostedNote() const { return host ? " (hosted in this process)" : ""; }
};

// The cell a command works on: --cell FILE (default: the built-in virtual cell, station/cells/
// virtual.toml, hosted in this process) and --virtual (host the file's own virtual twin here, built
// from the file, instead of reaching the cell's devices at its addresses). One declaration, so the
// commands that run the cell take them alike.
struct CellChoice {
  std::string file;
  bool host_virtual = false;

  // `hosts_by_default`: without --cell the command hosts the built-in virtual cell (scan, calibrate,
  // verify, hmi); otherwise it reaches the built-in cell's devices as served (devices).
  void addTo(CLI::App* cmd, bool hosts_by_default = true) {
    cmd->add_option("--cell", file,
                    hosts_by_default ? "The cell file (TOML; see `station cell check`); default: the built-in virtual cell, "
                                       "hosted here"
                                     : "The cell file (TOML; see `station cell check`); default: the built-in virtual cell, "
                                       "as `station sim serve` serves it");
    cmd->add_flag("--virtual", host_virtual,
                  "Host the cell file's virtual twin in this process (its simulated devices, built from the file) "
                  "instead of reaching the cell's devices");
  }
  // The cell's devices are simulated in this process.
  bool hosted() const { return file.empty() || host_virtual; }
  acquisition::CellConfig load() const {
    return file.empty() ? acquisition::virtualCell() : acquisition::loadCellConfig(file);
  }
  CommandCell open() const { return CommandCell{load(), hosted(), nullptr, std::nullopt}; }
};

}  // namespace stampscan::station
