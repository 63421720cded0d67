// The virtual CMM: an I++ DME server (spec 1.4.3) on TCP, in-process, with a Cartesian machine
// behind it. The station's CMM driver talks to it exactly as to a real controller
// (drivers/cmm/PROTOCOL.md lists the subset served).
//
// - One connection at a time (§9.3): the next client waits in the listen queue until the current one
//   disconnects. The machine (position, homed, active tool) outlives connections, as a real one does.
// - Moves (Home, GoTo) are straight lines with trapezoidal speed profiles (trapezoid_move.hpp) run in
//   real time, so AbortE during a move stops the machine where it is, and OnMoveReportE daemons
//   report the position while it moves.
// - Bad or out-of-context commands get the error responses of §8.2 (PROTOCOL.md has the table).
// - Tests can inject faults: an error for the next command, a dropped connection, silence.
//
// Thread safety: all methods may be called from any thread while the server runs.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::sim {

struct VirtualCmmConfig {
  std::string address = "127.0.0.1";
  std::uint16_t port = 1294;  // 0: the system picks a free port, readable from port() after start()

  // Machine coordinates, mm.
  std::array<double, 3> travel_min{-400, -300, -100};
  std::array<double, 3> travel_max{400, 300, 600};
  std::array<double, 3> home_position{0, 0, 500};
  std::array<double, 3> power_on_position{0, 0, 450};  // where the machine stands before Home()

  // Tool.GoToPar (§6.3.6), the same Min/Max/Def for every tool.
  double min_speed = 1, max_speed = 500, default_speed = 250;          // mm/s
  double min_accel = 10, max_accel = 2000, default_accel = 1000;      // mm/s^2

  std::vector<std::string> tools{"RefTool", "NoTool", "Probe1", "LaserDigitizer"};
  std::string initial_tool = "RefTool";
  double tool_change_seconds = 0.2;
  std::string machine_class = "CartCMM";  // GetMachineClass() (§6.3.2.8)
};

struct VirtualCmmStatus {
  std::array<double, 3> position{};  // now, also during a move
  bool homed = false;
  bool moving = false;
  bool connected = false;
  bool session_active = false;
  bool error_state = false;     // waiting for ClearAllErrors()
  std::string active_tool;
  std::size_t connections_served = 0;  // connections accepted so far
  std::size_t moves_completed = 0;
  std::size_t moves_aborted = 0;
};

class VirtualCmm {
 public:
  explicit VirtualCmm(VirtualCmmConfig config = {});
  ~VirtualCmm();  // stop()
  VirtualCmm(const VirtualCmm&) = delete;
  VirtualCmm& operator=(const VirtualCmm&) = delete;

  // Binds and listens, then serves on its own thread. Throws std::runtime_error naming the address
  // when it cannot bind. Starting twice is an error (std::logic_error).
  void start();
  // Closes the connection (stopping any move) and the port. Idempotent.
  void stop();
  std::uint16_t port() const;  // the bound port once started
  const VirtualCmmConfig& config() const;
  VirtualCmmStatus status() const;

  // Fault injection. The next command of the normal queue is answered with `error_number` (class
  // `severity`, or the §8.2 default) instead of being executed.
  void failNextCommand(int error_number, std::optional<int> severity = {});
  // Closes the current connection at once, as a crashed controller or a pulled cable would.
  void dropConnection();
  // While silent, the server reads and executes commands but sends nothing back.
  void setSilent(bool silent);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::sim
