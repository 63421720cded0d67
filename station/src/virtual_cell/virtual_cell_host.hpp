// The virtual cell as the commands that run a cell host it (scan, calibrate, verify, devices, hmi):
// the simulated world built from the cell file and, on it, the simulator's own parts as programs and
// the truth a scan is scored against. Nothing of the simulator shows here: the commands ask for a
// world in their own words and get back the cell config to reach its devices with, as they would a
// real cell's. Only this folder (station/src/virtual_cell/) includes sim/.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/part_program.hpp"
#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/jobs/scan_job.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::station {

// The options of the commands that host the virtual cell (scan, calibrate, verify) for its world:
// the seed that draws the sensors' true mounts, latency and noise, and a knock to the digitizer's
// mount. One declaration, so the three commands take them alike.
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
};

// The world a command asks the virtual cell to simulate.
struct VirtualWorld {
  // The default scan's session: its part's sample region, the cameras at a quarter of their
  // resolution; otherwise the whole part at the cameras' own.
  bool quick = false;
  std::optional<double> image_scale;  // the cameras' resolution factor, when not the session's
  // The simulator's own part on the fixture while no program puts its part there.
  std::string part = "dome", grid = "circle";
  bool calibration_artefacts = true;  // the reference sphere and the plate in the world
  VirtualWorldOptions options;
};

// The simulator's own parts as a virtual cell's programs (sim-dome-circle, ..., sim-pan-square-sample).
struct SimulatedProgramName {
  std::string name, part, grid;  // e.g. sim-pan-circle-sample, pan, circle
  bool sample_region = false;
  std::uint16_t line_number = 0;  // the number the line starts it by: 1, 2, ... in this list's order
};
std::vector<SimulatedProgramName> simulatedProgramNames();

// The name of the simulated part's program: sim-PART-GRID, with -sample for its sample region.
std::string simulatedProgramName(const std::string& part, const std::string& grid, bool sample_region);

// Writes the simulated part's program folder into `dir` (its nominal model, grid, material and a
// plan made for `cell`).
void writeSimulatedProgram(const SimulatedProgramName& program, const acquisition::CellConfig& cell,
                           const std::filesystem::path& dir);

// Returns when umockdev's preload library is active in this process (the virtual digitizer needs it);
// otherwise re-executes this program with it (virtual_digitizer_host.hpp) and does not return. Call
// it before printing anything, before starting threads and before reading what the new process
// would read again.
void requireUmockdevPreload();

// When the cell marks its digitizer virtual, hosts the virtual digitizer in this process (it lives
// as long as the returned handle) for a command that reaches the rest of the cell as served; null
// otherwise. Call it before any libusb context exists (the digitizer driver's, Aravis's).
std::shared_ptr<void> hostVirtualDigitizerOf(const acquisition::CellConfig& cell);

// A recording played on the virtual cell instead of its world: the plan as the machine ran it and
// the session as recorded.
struct RecordedSession {
  acquisition::ScanPlan plan;
  trace::SessionDescription session;
};

// The virtual cell's true sensors (its drawn ones plus the seed's deviation), against which a
// calibration on it is scored.
struct VirtualSensorTruth {
  Eigen::Isometry3d head_from_digitizer = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d head_from_left = Eigen::Isometry3d::Identity(), head_from_right = Eigen::Isometry3d::Identity();
  double left_fx_px = 0;
  std::int64_t digitizer_latency_ns = 0;
};

class VirtualCellHost {
 public:
  // The world on the cell the file describes. `config`'s cameras become the world's (at its image
  // scale: a quick session's quarter resolution), so that what the station is told of the cameras is
  // what they deliver. Nothing is served until start().
  VirtualCellHost(const VirtualWorld& world, acquisition::CellConfig& config);
  ~VirtualCellHost();
  VirtualCellHost(const VirtualCellHost&) = delete;
  VirtualCellHost& operator=(const VirtualCellHost&) = delete;

  // The program's part on the fixture (its simulated twin), instead of the world's own; on a
  // started cell, loaded at once.
  void useProgram(const acquisition::PartProgram& program);
  // The world's own part back on the fixture.
  void useOwnPart();
  // Plays the recorded trace instead of the world (before start()): its plan (or `plan_file`, the
  // plan as the machine ran it) and session. A damaged recording is refused unless accepted.
  RecordedSession replay(const std::string& trace, bool accept_damaged, const std::string& plan_file);

  // Serves the cell's devices in this process: the CMM and the PLC on free loopback ports, the
  // digitizer under umockdev, and the stereo pair unless `cameras` is false (it holds UDP 3956,
  // which one cell per machine can). Call it first thing: it may re-execute the program.
  void start(bool cameras);
  bool started() const;
  // The cell config to reach the served devices with: the file's, with the servers' actual ports.
  const acquisition::CellConfig& config() const;

  // What the simulator knows of a scan of `plan` (as the machine runs it) on the part now on the
  // fixture: the true elements, which of them the plan lets a sensor see whole, the digitizer's
  // true latency. The plan's part sweeps are given the elements each is predicted to see.
  jobs::SimulationTruth truthOfScan(acquisition::ScanPlan& plan);
  // The true elements of the part now on the fixture and the true latency, for a plan not known yet.
  jobs::SimulationTruth truthOfPart();

  VirtualSensorTruth sensorTruth() const;

  // The cell's door, to rehearse a fault.
  void openDoor();
  void closeDoor();

  // What a replay served, and the scan's result against `station process` on the recording.
  void printReplay(const jobs::ScanJobResult& result) const;
  bool replaying() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace stampscan::station
