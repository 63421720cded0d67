// The ScanRunner plays a ScanPlan on a cell and records everything into a TraceSink as it arrives:
// the CMM's positions (its move-report daemon), the digitizer's profiles, the PLC's state, the
// devices' clock pairs, the sweeps' and scenes' brackets, and the session description. The same
// runner drives a real cell and the virtual one; it only sees the drivers.
//
// A run, in order:
//  1. The plan is checked against the machine's limits: a plan that leaves the travel, asks for a
//     speed or a head angle the CMM refuses, is refused (ScanError) before anything moves.
//  2. Checks before motion: every device connects and answers; the caller's own check
//     (ScanRunParams::before_motion, with the devices' identities); the PLC reports the door closed, the
//     e-stop chain and the light curtain healthy and the air on; the part is clamped (the runner
//     asks the PLC to clamp and waits). A failed check is a ScanError with one line naming it.
//  3. The CMM is homed if it is not; move reports start; for each step the head travels to the
//     sweep's start, the laser shutter opens, the digitizer streams, the head sweeps, then the
//     shutter closes. Each sweep is bracketed by CmmEvents sweep_begin/sweep_end ("part sweep 3")
//     and each scene by SceneMarkers, as the measuring path (registration::measureScan) expects.
//  4. The head parks and the clamp opens.
// Digitizer sequence gaps are counted; a sweep that lost more than max_lost_profiles_per_sweep is
// run again once, the first run marked "sweep_discarded" (the measuring path leaves it out).
// Faults mid-scan: the PLC's door, e-stop or curtain (SafetyInterlock aborts the move at once), an
// operator abort (abort(), e.g. from Ctrl-C) or a device error end the run as Aborted: the shutter
// is closed, the digitizer stopped, an "abort" CmmEvent records why, and the trace stays readable.
//
// Stereo steps: the head travels to the pose, settles, and both cameras are triggered in software
// (drivers::camera::StereoPair); the pair of frames goes to the trace with the trigger id, each
// camera's clock pair beside it. A pair that does not arrive within frame_timeout (a camera lost:
// the driver reconnects by itself) is marked with a "view_missing" CmmEvent and the scan goes on.
//
// Thread safety: run() blocks; abort() may be called from any thread (a signal handler must not:
// set a flag and call it from a thread). The sink is written from the devices' threads, one message
// at a time under the runner's lock; the observer is called from the thread that calls run().
#pragma once

#include "stampscan/acquisition/scan_fault.hpp"
#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/acquisition/station_clock.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/acquisition/trace/trace_sink.hpp"
#include "stampscan/drivers/camera/gige_camera.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/drivers/digitizer/usb_digitizer.hpp"
#include "stampscan/drivers/plc/modbus_plc.hpp"

#include <atomic>
#include <chrono>
#include <functional>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::acquisition {

// The devices a scan uses, connected or not; owned by the caller, alive for the run. The cameras
// are needed only by plans with stereo steps.
struct CellDevices {
  drivers::cmm::IppCmm& cmm;
  drivers::plc::ModbusPlc& plc;
  drivers::digitizer::UsbDigitizer& digitizer;
  drivers::camera::GigECamera* left_camera = nullptr;
  drivers::camera::GigECamera* right_camera = nullptr;
};

// Thrown when a check before motion fails; nothing has moved. The text is one line for the operator;
// the kind says which check (an open door, a silent device, ...), Other for a plan or setup problem.
class ScanError : public FaultError {
 public:
  explicit ScanError(const std::string& text, FaultKind kind = FaultKind::Other) : FaultError(kind, text) {}
};

struct ScanProgress {
  std::size_t step = 0, steps = 0;  // steps done, of the plan's
  std::string doing;                // "part sweep 3", "travel", "homing", ...
  double elapsed_s = 0;
  double remaining_s = 0;           // from the plan's motion time still ahead
  std::uint64_t profiles = 0, lost_profiles = 0, positions = 0;
};

class ScanObserver {
 public:
  virtual ~ScanObserver() = default;
  virtual void checkPassed(const std::string& /*what*/) {}
  virtual void progress(const ScanProgress& /*progress*/) {}
  // A safety trip, a device fault or lost data during the run; `what` is for the operator.
  virtual void safetyEvent(FaultKind /*kind*/, const std::string& /*what*/) {}
};

struct ScanRunParams {
  // The session description to record: the runner fills in the part, grid and plan from the plan and
  // the digitizer's profile format from the device; the caller gives the cell's geometry (digitizer
  // mount and range, the reference sphere) and the part id.
  trace::SessionDescription session;
  MachineLimits limits;
  double report_interval_s = 0.1;  // the CMM's move reports (I++ DME allows 0.1 s at the fastest)
  std::chrono::milliseconds clamp_timeout{3000};
  std::chrono::milliseconds plc_state_period{100};
  // A sweep that loses more profiles than this (digitizer sequence gaps) is run again, once.
  std::uint64_t max_lost_profiles_per_sweep = 10;
  // A stereo view whose pair of frames has not arrived by then is marked missing.
  std::chrono::milliseconds frame_timeout{10000};
  // The caller's own check before motion (e.g. that the calibration in use belongs to these
  // sensors): called once every device answers, with their identities, before the interlocks are
  // read and the part clamped. It refuses the run by throwing ScanError; nothing has moved then.
  std::function<void(const std::vector<drivers::DeviceIdentity>& devices)> before_motion;
};

struct ScanRunResult {
  bool completed = false;
  std::string abort_reason;  // when not completed
  FaultKind abort_kind = FaultKind::Other;  // when not completed: what stopped it
  std::size_t steps_done = 0, sweeps_done = 0, views_done = 0, views_missing = 0;
  std::size_t sweeps_repeated = 0;  // run again after losing profiles
  std::size_t sweeps_over_loss_limit = 0;  // lost too many profiles even when repeated: kept as they are
  std::uint64_t profiles = 0, lost_profiles = 0, positions = 0, plc_states = 0;
  double wall_seconds = 0;    // from the first motion to parked
  double motion_seconds = 0;  // what the plan needs (motionSeconds), for comparison
  // Where the wall time went (seconds): the CMM's moves (command to arrival), the settling before
  // each view, the wait for each view's frames after the trigger, the digitizer's clock pairs, its
  // start, drain and stop around each sweep; `other` is the rest (the shutter, pose reads, parking's
  // checks, the observer).
  struct TimeSpent {
    double moving = 0, settling = 0, frames = 0, clock_sync = 0, digitizer = 0, other = 0;
  } spent;
  std::vector<drivers::DeviceIdentity> devices;
  std::vector<std::string> safety_events;
};

class ScanRunner {
 public:
  ScanRunner(CellDevices devices, trace::TraceSink& sink, const StationClock& clock, ScanObserver* observer = nullptr);
  ~ScanRunner();
  ScanRunner(const ScanRunner&) = delete;
  ScanRunner& operator=(const ScanRunner&) = delete;

  // Throws ScanError for a plan or a check that fails before motion. Returns completed = false when
  // the run was aborted after motion began (the reason says why).
  ScanRunResult run(const ScanPlan& plan, const ScanRunParams& params);
  // Stops the run: the CMM aborts its move, the run ends Aborted with `reason`. Any thread. Called
  // before run(), the run ends at its first step (a runner plays one plan).
  void abort(const std::string& reason);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::acquisition
