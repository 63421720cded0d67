// `station sim serve [--cell CELL.toml] [--part pan|dome] [--for SECONDS]`: runs the virtual cell
// (one simulated world, sim/virtual_cell) with its devices on their real protocols until
// interrupted, so that the station and independent tools (mbpoll, arv-tool, a plain TCP client
// speaking I++ DME) can talk to them. Loopback only unless the cell file says
// otherwise. The virtual digitizer is not among them: see virtual_digitizer_host.hpp.
//
// Each device runs in a process of its own under a supervisor (sim/supervised_cell.hpp), which
// starts again one that stops unexpectedly; this command only sets it up, prints and waits.
#include "stampscan/station/measuring_priority.hpp"
#include "stampscan/sim/supervised_cell.hpp"
#include "virtual_digitizer_host.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/station/commands.hpp"

#include <chrono>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <memory>
#include <string>

namespace stampscan::station {

using acquisition::CellConfig;
using acquisition::loadCellConfig;
using acquisition::virtualCell;

CommandRunner addServeSubcommand(CLI::App* sim) {
  struct Options {
    std::string cell, part = "pan", replay;
    double seconds = 0;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* cmd = sim->add_subcommand("serve", "Run the virtual cell (CMM over I++ DME, PLC over Modbus TCP, GigE Vision cameras) until interrupted");
  cmd->add_option("--cell", opt->cell, "Cell configuration (TOML); default: the built-in virtual cell");
  cmd->add_option("--part", opt->part, "The part on the fixture of the simulated world")->check(CLI::IsMember({"pan", "dome"}));
  cmd->add_option("--replay", opt->replay,
                  "Serve a recorded trace instead of the simulated world: the CMM follows its head track, the "
                  "cameras serve its frames (the digitizer is hosted by the command that scans)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--for", opt->seconds, "Stop after this many seconds (default: run until Ctrl-C)")->check(CLI::PositiveNumber);
  return [opt]() {
    const CellConfig cell = opt->cell.empty() ? virtualCell() : loadCellConfig(opt->cell);
    // Block the stop signals before any device thread starts, so that only sigtimedwait sees them.
    sigset_t stop;
    sigemptyset(&stop);
    sigaddset(&stop, SIGINT);
    sigaddset(&stop, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop, nullptr);
    // The virtual cell stands for the cell's own controllers, which keep their time whatever the
    // station's computer runs: at the priority of the commands that measure on it, not below.
    const MeasuringPriority priority = raiseMeasuringPriority();

    // The virtual cell as one world (sim/virtual_cell): the cameras render the part, sphere and
    // plate from the head pose the CMM has, whoever moves it. The second camera address is added
    // to lo when missing, which needs root.
    // The world is the cell file's: its sensors as drawn (the cameras at the file's resolution, so
    // that what a station reads in the same file is what the cameras deliver), its artefacts where
    // the file puts them.
    sim::VirtualCellOptions world = servedDevicesOf(cell);
    world.world = sim::ScanParams::quick();
    world.world.image_scale = 1;
    world.world.setCell(cell);
    world.world.part = opt->part == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan;
    sim::SupervisedVirtualCell served(world, opt->replay);
    const int cmm_port = served.cmmPort(), plc_port = served.plcPort();
    std::printf("station sim serve: %s (each device in a process of its own)%s\n", cell.name.c_str(),
                opt->replay.empty() ? "" : (", replaying " + opt->replay).c_str());
    std::printf("  priority    %s\n", priority.describe().c_str());
    std::printf("  cmm         I++ DME on %s:%d   (try: printf '00001 StartSession()\\r\\n' | nc %s %d)\n",
                cell.cmm.host.c_str(), cmm_port, cell.cmm.host.c_str(), cmm_port);
    // The discrete inputs where the cell file's map puts them (mbpoll numbers references from 1).
    const drivers::plc::AddressSpan inputs = cell.plc_registers.span(drivers::plc::RegisterKind::DiscreteInput);
    std::printf("  plc         Modbus TCP on %s:%d   (try: mbpoll -m tcp -a %d -t 1 -r %d -c %d -1 -p %d %s)\n",
                cell.plc.host.c_str(), plc_port, cell.plc_unit_id, inputs.first + 1, inputs.count, plc_port,
                cell.plc.host.c_str());
    std::printf("  cameras     GigE Vision %s on %s, %s on %s   (try: arv-tool-0.8)\n",
                cell.left_camera.serial.c_str(), cell.left_camera.address.c_str(), cell.right_camera.serial.c_str(),
                cell.right_camera.address.c_str());
    // The virtual digitizer is a USB device under umockdev: it exists only inside the process that
    // hosts it, so it cannot be served to others from here.
    if (cell.digitizer_virtual)
      std::printf("  digitizer   not served here: a USB device under umockdev, hosted in-process by `station devices`"
                  " (see sim/virtual_digitizer)\n");
    else
      std::printf("  digitizer   not served: this cell's digitizer is a USB device (%04x:%04x), not virtual\n",
                  cell.digitizer_vendor, cell.digitizer_product);
    std::printf("  running; Ctrl-C stops%s\n", opt->seconds > 0 ? " (or the --for time)" : "");
    std::fflush(stdout);
    // Until a signal or the --for time; a device that stops unexpectedly is started again (a
    // fault in one device must not take the cell down).
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(opt->seconds > 0 ? opt->seconds : 3.15e7);
    const char* why = "time up";
    while (std::chrono::steady_clock::now() < until) {
      timespec slice{0, 200'000'000};
      if (sigtimedwait(&stop, nullptr, &slice) > 0) {
        why = "signal";
        break;
      }
      served.restartStopped([](const std::string& line) {
        std::printf("  %s\n", line.c_str());
        std::fflush(stdout);
      });
    }
    std::printf("  stopping (%s)\n", why);
    return 0;
  };
}

}  // namespace stampscan::station
