// The options of the commands that host the virtual cell (scan, calibrate, verify) for its world:
// the seed that draws the sensors' true mounts, latency and noise, and a knock to the digitizer's
// mount. One declaration, so the three commands take them alike.
#pragma once

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

}  // namespace stampscan::station
