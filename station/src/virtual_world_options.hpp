// The options of the commands that host the virtual cell (scan, calibrate, verify) for its world:
// the seed that draws the sensors' true mounts, latency and noise, and a knock to the digitizer's
// mount. One declaration, so the three commands take them alike.
#pragma once

#include "stampscan/acquisition/calibration_plan.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <vector>

namespace stampscan::station {

struct VirtualWorldOptions {
  std::uint64_t seed = 1;
  std::vector<double> mount_shift;  // empty, or X, Y, Z in mm

  void addTo(CLI::App* cmd) {
    cmd->add_option("--seed", seed, "The virtual cell's seed (sensor noise, the sensors' true mounts and latency)");
    cmd->add_option("--shift-digitizer-mount", mount_shift,
                    "Virtual cell: knock the digitizer's true mount by X,Y,Z mm (head frame), as if it had moved")
        ->expected(3)
        ->delimiter(',');
  }
  void applyTo(sim::ScanParams& world) const {
    world.seed = seed;
    if (mount_shift.size() == 3) world.digitizer_mount_shift = sim::Vec3(mount_shift[0], mount_shift[1], mount_shift[2]);
  }
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
};

// The simulated world of a cell: `world` (its part, its sessions' size and image scale) on the
// cell the file describes. When the world is hosted as the cell's virtual twin, the cell's cameras
// become the world's: at its image scale (a quick session's quarter resolution), so that what the
// station is told of the cameras is what they deliver.
inline sim::ScanParams worldOnCell(sim::ScanParams world, acquisition::CellConfig& config, bool hosted) {
  if (hosted && world.image_scale != 1) {
    config.geometry.cameras = acquisition::atResolution(config.geometry.cameras, world.image_scale);
    world.image_scale = 1;
  }
  world.setCell(config);
  return world;
}

}  // namespace stampscan::station
