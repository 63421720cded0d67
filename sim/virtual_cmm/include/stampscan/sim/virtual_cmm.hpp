// The virtual CMM: an I++ DME server (spec 1.4.3) on TCP, in-process, with a Cartesian machine
// behind it. The station's CMM driver talks to it exactly as to a real controller
// (drivers/cmm/PROTOCOL.md lists the subset served).
//
// - One connection at a time (§9.3). A second client waits up to second_client_wait for the current
//   one to hang up, then is served; otherwise it is refused with one line, `E0000 ! Error(3, 0511,
//   "Connect", "Error processing method")`, and closed, rather than left hanging. A client that sends
//   nothing for idle_timeout while none of its commands runs is disconnected, so that a vanished
//   station cannot hold the machine for ever. The machine (position, homed, active tool) outlives
//   connections, as a real one does.
// - A response line goes out whole within send_timeout or the connection is closed: a client that
//   does not read never receives a line cut short and run into the next one.
// - When the process runs out of file descriptors, the server backs off and accepts again later
//   instead of spinning.
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
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::sim {

// A move the virtual CMM follows instead of planning its own (VirtualCmmConfig::follow).
struct FollowedMove {
  double seconds = 0;  // from the command to the arrival
  // The six axes (mm, degrees) `t` seconds after the command, for 0 <= t <= seconds.
  std::function<std::array<double, 6>(double t)> pose_at;
  // When the recorded CMM reported during the move (s since the command, rising): move reports
  // (OnMoveReportE) then go out at these instants instead of on the daemon's own schedule, so that a
  // replayed head track is sampled where the recorded one was. Empty: the usual schedule.
  std::vector<double> report_at;
};

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

  // Connection handling. The spec sets no idle limit (§6.3.1.2 even lets a client idle after
  // EndSession); a station keeps its session open through a scan, idle for seconds between moves and
  // for minutes while the operator loads a part, and a running move (however long) is not idleness.
  // Five minutes frees the machine from a station that vanished without closing its connection.
  std::chrono::milliseconds idle_timeout{std::chrono::minutes(5)};
  // How long one response line may take to go out to a client that reads slowly.
  std::chrono::milliseconds send_timeout{std::chrono::seconds(5)};
  // How long a second client waits for the current one to hang up before it is refused. Long enough
  // for a station that reconnects (the old session's teardown takes milliseconds).
  std::chrono::milliseconds second_client_wait{std::chrono::seconds(2)};

  // Replay: asked at the start of every move (GoTo, Home) with the six axes where the machine stands
  // and where it is sent (X, Y, Z in mm; Tool.A, Tool.B, Tool.C in degrees) and the time; a move it
  // returns is followed instead of the machine's own kinematics (a recorded session plays back).
  std::function<std::optional<FollowedMove>(const std::array<double, 6>& from, const std::array<double, 6>& to,
                                            std::chrono::steady_clock::time_point now)>
      follow;
};

struct VirtualCmmStatus {
  std::array<double, 3> position{};  // now, also during a move
  // The head's angles a, b, c in radians (not the wire's degrees), now, also during a move, sampled
  // at the same instant as `position`: a simulated world renders the sensors from this pose.
  double head_a = 0, head_b = 0, head_c = 0;
  // Where the move in progress ends (the position and head angles as above; at rest, where the
  // machine stands): a simulated world may prepare what a sensor will see there before it arrives.
  std::array<double, 3> destination{};
  double destination_a = 0, destination_b = 0, destination_c = 0;
  bool homed = false;
  bool moving = false;
  bool connected = false;
  bool session_active = false;
  bool error_state = false;     // waiting for ClearAllErrors()
  std::string active_tool;
  std::size_t connections_served = 0;  // connections served so far
  std::size_t connections_refused = 0;  // second clients refused while another was served
  std::size_t idle_disconnects = 0;     // connections closed after idle_timeout
  std::size_t slow_reader_disconnects = 0;  // connections closed because a line missed send_timeout
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
