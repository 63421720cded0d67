// Hosting the cell's virtual digitizer in the station's own process. The virtual digitizer is a USB
// device under umockdev (sim/virtual_digitizer): it exists only inside a process that runs with
// umockdev's preload library, so `station sim serve` cannot offer it to other processes the way it
// serves the CMM, the PLC and the cameras. A command that talks to the cell's digitizer hosts it
// instead, and the unmodified USB driver then finds it on the (mocked) bus like the real head.
#pragma once

#include "stampscan/sim/virtual_cell.hpp"
#include "stampscan/sim/virtual_digitizer.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/jobs/scan_job.hpp"
#include "virtual_cell_host.hpp"

#include <memory>

namespace stampscan::station {

using acquisition::CellConfig;
using acquisition::loadCellConfig;
using acquisition::virtualCell;

// The library umockdev-wrapper preloads; found by the dynamic loader's usual search.
inline constexpr const char* kUmockdevPreload = "libumockdev-preload.so.0";

// requireUmockdevPreload() (virtual_cell_host.hpp) re-executes this program (/proc/self/exe, the
// same arguments) with the library added to LD_PRELOAD; a marker in the environment keeps the new
// process from trying again. Under AddressSanitizer the ASan runtime stays first in LD_PRELOAD, as it
// insists on coming first. It throws std::runtime_error, naming the library and how to install it,
// when it cannot be loaded or did not load after the re-exec.

// When the cell marks its digitizer virtual: requires the preload (above), then builds the virtual
// digitizer (with the cell's serial when it names one) and returns it; it lives as long as the
// returned object. Otherwise returns null. The testbed redirects /sys and /dev for the whole process
// and libusb enumerates when a context is made, so call it before any libusb context exists: before
// the digitizer driver connects and before Aravis looks for cameras (it has a libusb context too).
std::unique_ptr<sim::VirtualDigitizer> hostVirtualDigitizer(const CellConfig& cell, sim::VirtualDigitizerOptions options = {});

// The virtual cell's devices where the cell file puts them: the CMM's and the PLC's addresses and
// ports, the PLC's unit and register map, both cameras' addresses and serials (cameras served). The
// world and the replay are the caller's.
sim::VirtualCellOptions servedDevicesOf(const CellConfig& cell);

}  // namespace stampscan::station

namespace stampscan::station {

// The whole virtual cell hosted in this process as one world (sim/virtual_cell): the CMM and the PLC
// serving on free loopback ports, the digitizer under umockdev rendering the world. Construct it
// first thing (it may re-execute the program, see requireUmockdevPreload). config() is the cell
// config to reach it with: the base with the servers' actual ports.
class HostedVirtualCell {
 public:
  // With `replay`, the cell plays a recorded session instead of the world (sim/cell_replay.hpp).
  // Without `cameras` the stereo pair is left out: it holds UDP 3956, which one cell per machine can.
  HostedVirtualCell(const sim::ScanParams& world, const acquisition::CellConfig& base,
                    std::shared_ptr<sim::CellReplay> replay = nullptr, bool cameras = true);
  ~HostedVirtualCell();
  HostedVirtualCell(const HostedVirtualCell&) = delete;
  HostedVirtualCell& operator=(const HostedVirtualCell&) = delete;

  const acquisition::CellConfig& config() const { return config_; }
  sim::VirtualCell& cell() { return *cell_; }

  // What the simulator knows of a scan of `plan` (as the machine runs it) on the cell's part, to
  // score the scan with: the true elements where the fixture holds the part, which of them the plan
  // lets a sensor see whole, and the digitizer's true latency. The plan's part sweeps are given the
  // elements the simulator predicts each sees (SweepStep::expected_elements). `world` is the one
  // the cell simulates (its part and grid).
  jobs::SimulationTruth truthOfScan(const sim::ScanParams& world, acquisition::ScanPlan& plan);

 private:
  std::unique_ptr<sim::VirtualCell> cell_;
  std::unique_ptr<sim::VirtualDigitizer> digitizer_;
  acquisition::CellConfig config_;
};

}  // namespace stampscan::station
