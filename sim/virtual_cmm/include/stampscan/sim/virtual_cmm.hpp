// The virtual CMM: an I++ DME server (spec 1.4.3) on TCP, in-process, with a Cartesian machine
// behind it. The station's CMM driver talks to it exactly as to a real controller
// (drivers/cmm/PROTOCOL.md lists the subset served).
//
// - One connection at a time (§9.3): the next client waits in the listen queue until the current one
//   disconnects. The machine (position, homed, active tool) outlives connections, as a real one does.
// - Moves (Home, GoTo) are straight lines with trapezoidal speed profiles (trapezoid_move.hpp) run in
//   real time, so AbortE during a move stops the machine where it is, and OnMoveReportE daemons
//   report the position while it moves.
// - An articulating probe head with angles Tool.A, Tool.B, Tool.C (§6.3.8), continuous or indexing,
//   turned by GoTo together with X, Y, Z: all axes of a GoTo start and finish together on one
//   trapezoidal progress (§6.3.2.12). Angles are degrees on the wire (§6.1.2) and in the config,
//   radians in VirtualCmmStatus. The head's frame is HeadState's (sim/cmm_motion.hpp):
//   translation(ram) * Rz(b) * Rx(a) * Rz(c); PROTOCOL.md has the details.
// - Bad or out-of-context commands get the error responses of §8.2 (PROTOCOL.md has the table).
// - Tests can inject faults: an error for the next command, a dropped connection, silence.
//
// Thread safety: all methods may be called from any thread while the server runs.
#pragma once

#include <array>
#include <chrono>
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

  // The probe head, in degrees as on the wire (§6.1.2), in the order A, B, C. A tilts about the
  // ram's x axis, B turns about its z axis; C is fixed at 0 (its range [0, 0]) unless configured.
  // An angle outside its range is refused with 2505 "Specified angle out of range".
  enum class HeadKind {
    Continuous,  // any angle inside the range: the virtual cell's plans use small ones such as 2 degrees
    Indexing,    // only multiples of head_index_step_deg; others are refused with 2505 as well
  };
  HeadKind head_kind = HeadKind::Continuous;
  double head_index_step_deg = 7.5;
  std::array<double, 3> head_min_deg{-115, -180, 0};
  std::array<double, 3> head_max_deg{115, 180, 0};
  std::array<double, 3> head_power_on_deg{0, 0, 0};  // Home() does not turn the head
  // The head's own limits; a GoTo is as slow as its slowest axis group needs (cmm_machine.hpp).
  double head_max_rate_deg_s = 90, head_accel_deg_s2 = 360;

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
  // The head's angles a, b, c in radians (not the wire's degrees), now, also during a move, sampled
  // at the same instant as `position`: a simulated world renders the sensors from this pose.
  double head_a = 0, head_b = 0, head_c = 0;
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
  // Throws std::invalid_argument for a head configuration that cannot work (an indexing step or a
  // rate <= 0, a power-on angle outside its range).
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
  // The machine's position and head angles at `when` (steady clock) during the current move or at
  // rest, for a simulated sensor that renders the world at its own exposure time; the other fields
  // as status().
  VirtualCmmStatus statusAt(std::chrono::steady_clock::time_point when) const;

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
