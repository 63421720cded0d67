// The CMM driver: an I++ DME client (spec 1.4.3) for a Cartesian CMM controller on TCP port 1294.
// The same code drives a real controller and the virtual CMM of sim/virtual_cmm; only the address
// differs. drivers/cmm/PROTOCOL.md lists the subset of I++ DME it speaks.
//
// The probe head. A CMM with an articulating head has the tool's rotary axes Tool.A, Tool.B and,
// on some heads, Tool.C (§6.3.8). The driver speaks of them as a ToolOrientation in radians, the
// house's unit, and converts to the wire's degrees (§6.1.2) and back. A tilts about the ram's x axis,
// B turns about its z axis, C rolls about the tool's own axis: the head frame is translation(ram) *
// Rz(b) * Rx(a) * Rz(c), sim/cmm_motion.hpp's HeadState::pose(). goTo() with an orientation moves
// all axes together (§6.3.2.12); pose() reads position and angles in one Get; move reports carry the
// angles when asked. IppCmmOptions::head_has_c says whether Tool.C exists: without it the driver
// never names Tool.C, so that a two-axis head (ToolAB) is not sent an axis it lacks.
//
// connect() opens the TCP connection and the session (StartSession, §6.3.1.1); disconnect() ends it
// (EndSession, §6.3.1.2). Every call is one or more transactions (§6.2.3), each bounded by a timeout.
//
// Errors. When the CMM answers `!` with class 2 or more (§8.1) the driver records a Device fault
// naming the spec's error number and text, asks GetErrorInfo (§6.3.1.6), sends ClearAllErrors
// (§6.3.1.7) and, if that worked, is Ready again; the call throws IppError. Warnings (class 0 and 1)
// do not fail a call. A silent CMM ends the call with fault "timeout", a broken connection with fault
// "disconnected"; in both cases connect() again. While faulted, calls throw DeviceError "not-ready"
// until clearAllErrors() or connect() succeeds.
//
// Thread safety: calls are serialised (one transaction sequence at a time), except abort(), which
// may be called from another thread while home(), goTo() or changeTool() runs. The move report
// callback runs on the driver's reader thread: keep it short and do not call the driver from it.
#pragma once

#include "stampscan/drivers/cmm/ipp_protocol.hpp"
#include "stampscan/drivers/device.hpp"

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::drivers::cmm {

namespace detail {
class IppChannel;
struct Transaction;
}  // namespace detail

struct IppCmmOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = ipp::kDefaultPort;
  std::chrono::milliseconds connect_timeout{3000};
  // Each transaction that does not move the machine, from sending to its `%`.
  std::chrono::milliseconds reply_timeout{3000};
  // Home(), GoTo() and ChangeTool(), from sending to `%`: the longest move of the cell plus margin.
  std::chrono::milliseconds motion_timeout{120000};
  // Ask the CMM to stamp each move report with its own clock (the SS.Time() extension of
  // PROTOCOL.md). The virtual CMM has it; a real controller answers 0510 Bad property.
  bool device_time_in_reports = false;
  // The head has a third angle, Tool.C (a ToolABC, §6.3.8). Without it ToolOrientation::c must be 0.
  bool head_has_c = false;
};

// Machine coordinates of the active tool, mm (§6.1.2).
struct CmmPosition {
  double x = 0, y = 0, z = 0;
};

// The probe head's angles Tool.A, Tool.B, Tool.C in radians (degrees only on the wire, §6.1.2).
// a: tilt about the ram's x axis; b: turn about its z axis, applied after a; c: roll about the
// tool's own axis, applied first. The head frame is translation(ram) * Rz(b) * Rx(a) * Rz(c).
struct ToolOrientation {
  double a = 0, b = 0, c = 0;

  static ToolOrientation fromDegrees(double a_deg, double b_deg, double c_deg = 0);
  double aDegrees() const;
  double bDegrees() const;
  double cDegrees() const;
};

// Where the active tool is and how the head is turned, read at one instant.
struct CmmPose {
  CmmPosition position;
  ToolOrientation orientation;
};

struct MoveReport {
  // When the line arrived: std::chrono::steady_clock in ns (a reading for deadlines and intervals,
  // not a date; acquisition::StationClock::fromSteady puts it on the station clock).
  std::int64_t arrival_steady_ns = 0;
  std::optional<double> device_time_s;   // the CMM's clock (s since StartSession), if asked for
  CmmPosition position;
  std::optional<ToolOrientation> orientation;  // with MoveReportContent::PositionAndOrientation
};
using MoveReportCallback = std::function<void(const MoveReport&)>;

// What each move report carries besides the position (startMoveReports()).
enum class MoveReportContent {
  Position,                 // X(), Y(), Z()
  PositionAndOrientation,   // also Tool.A(), Tool.B() (and Tool.C() with IppCmmOptions::head_has_c)
};

enum class MoveOutcome { Reached, Aborted };

// An error response of the CMM (code "device-error"), with its I++ DME fields.
class IppError : public DeviceError {
 public:
  IppError(const std::string& device, ipp::ErrorReport report, std::string info);
  const ipp::ErrorReport& report() const { return report_; }
  const std::string& info() const { return info_; }  // what GetErrorInfo said, if it answered

 private:
  ipp::ErrorReport report_;
  std::string info_;
};

class IppCmm : public Device {
 public:
  explicit IppCmm(IppCmmOptions options, std::string name = "cmm");
  ~IppCmm() override;

  const IppCmmOptions& options() const { return options_; }

  // Home() (§6.3.2.1): the CMM must be homed before it moves; Aborted when abort() stopped it.
  // IsHomed() (§6.3.2.2).
  MoveOutcome home();
  bool isHomed();
  // EnableUser() / DisableUser() (§6.3.2.3-4): the jog box. Every move disables it again.
  void enableUser();
  void disableUser();

  // GoTo(X(), Y(), Z()) (§6.3.2.12), blocking until the CMM reports the move complete. `speed` (mm/s)
  // applies to this move only; without it the speed of setSpeed() applies. Aborted when abort()
  // stopped it. Throws std::invalid_argument for a non-finite target or a speed <= 0. The head's
  // angles are not named, so they keep their values (§6.3.2.12).
  MoveOutcome goTo(const CmmPosition& target, std::optional<double> speed = {});
  // GoTo(X(), Y(), Z(), Tool.A(), Tool.B()[, Tool.C()]) (§6.3.2.12, §6.3.8): the ram and the head
  // start together and finish together. An angle the head cannot take (outside its range, or off an
  // indexing head's grid) is refused by the CMM with 2505 and throws IppError; nothing moves. Also
  // throws std::invalid_argument for a non-finite angle, or c != 0 without head_has_c.
  MoveOutcome goTo(const CmmPosition& target, const ToolOrientation& orientation, std::optional<double> speed = {});
  // Get(X(), Y(), Z()) (§6.3.2.11).
  CmmPosition position();
  // Get(X(), Y(), Z(), Tool.A(), Tool.B()[, Tool.C()]) (§6.3.2.11): one Get, so one instant.
  CmmPose pose();

  // Tool.GoToPar.Speed and .Accel of the active tool (§6.3.1.9, §6.3.1.11, §6.3.6). The setters
  // return the value in effect: the CMM clamps to its Min/Max with warning 0504.
  double setSpeed(double mm_per_s);
  double speed();
  double setAcceleration(double mm_per_s2);
  double acceleration();

  // ChangeTool("name") (§6.3.2.18); the new tool's GoToPar defaults apply afterwards (§6.3.6).
  // An abort() meanwhile may leave the old tool active: ask currentTool().
  void changeTool(const std::string& tool);
  // GetProp(Tool.Name()) (§6.3.10).
  std::string currentTool();
  // EnumTools() (§6.3.2.23).
  std::vector<std::string> tools();

  // OnMoveReportE(Time(interval), X(), Y(), Z()[, Tool.A(), Tool.B()[, Tool.C()]]) (§6.3.2.7): a
  // daemon on an event tag reporting the position (and with PositionAndOrientation the head's
  // angles, MoveReport::orientation) while the machine moves, at most 10 times a second (interval
  // >= 0.1 s). Replaces a running one. Reports stop with stopMoveReports() (StopDaemon, §6.3.1.3)
  // or the connection.
  void startMoveReports(double interval_s, MoveReportCallback callback,
                        MoveReportContent content = MoveReportContent::Position);
  void stopMoveReports();

  // AbortE() (§6.3.1.5) then ClearAllErrors(): stops the machine where it is; a goTo() in progress
  // returns Aborted. Safe to call from another thread; Ready afterwards.
  void abort();
  // ClearAllErrors() (§6.3.1.7); also takes the driver from Faulted back to Ready.
  void clearAllErrors();
  // GetErrorInfo(number) (§6.3.1.6): the CMM's explanation of its last error with that number.
  std::string errorInfo(int error_number);
  // Errors the CMM sent unasked, on tag E0000 (§6.2.4.1); class 2 and above also fault the driver.
  std::vector<ipp::ErrorReport> unsolicitedErrors() const;

 protected:
  void connectDevice() override;
  void disconnectDevice() noexcept override;
  DeviceIdentity identifyDevice() override;
  void checkDevice() override;  // GetErrStatusE() (§6.3.2.9)

 private:
  struct Request;
  struct Result;
  class BusyScope;

  std::unique_lock<std::mutex> beginCall();  // serialises calls; throws unless Ready
  std::shared_ptr<detail::IppChannel> channel() const;
  void markUnresponsive();
  Result transact(const Request& request);
  Result command(const Request& request);
  [[noreturn]] void recoverAndThrow(const Result& result);
  bool abortedByUs(const Result& result);
  // Waits (when `wait`) until no abort() is under way; returns how many have begun so far.
  std::uint64_t waitWhileAborting(bool wait);
  double readProperty(const std::string& property);
  double writeProperty(const std::string& property, double value);
  void applySpeed(double mm_per_s);
  void readMotionParameters();
  void onMoveReportLine(const ipp::Reply& reply, bool with_orientation);
  MoveOutcome move(std::vector<ipp::Argument> axes, std::optional<double> speed);
  std::vector<ipp::Argument> headAxes(const ToolOrientation* orientation) const;  // Tool.A(..) or Tool.A()
  std::optional<ToolOrientation> orientationIn(const std::vector<ipp::Argument>& items) const;
  [[noreturn]] void badResponse(const std::string& what, const Result& result);

  IppCmmOptions options_;

  std::mutex call_mutex_;  // one public call at a time (abort() excepted)

  mutable std::mutex channel_mutex_;
  std::shared_ptr<detail::IppChannel> channel_;
  bool responsive_ = false;  // false after a timeout: disconnect() then skips EndSession
  std::vector<ipp::ErrorReport> unsolicited_;

  std::mutex abort_mutex_;
  std::condition_variable abort_done_;
  bool aborting_ = false;
  std::uint64_t aborts_begun_ = 0;

  // Tool.GoToPar.Speed: what the CMM has now, and what moves without their own speed use.
  double cmm_speed_ = 0;
  double speed_setting_ = 0;

  std::mutex reports_mutex_;
  std::optional<ipp::Tag> report_tag_;
  std::shared_ptr<MoveReportCallback> report_callback_;
};

}  // namespace stampscan::drivers::cmm
