// The work the panel starts on the cell: a scan (jobs::ScanJob, as `station scan` runs it), a
// check of the digitizer (jobs::VerifyJob, as `station verify`) or a calibration
// (jobs::CalibrateJob), one at a time. The panel only
// chooses what to start; the jobs are the CLI's own, and their observer turns what they report into
// events for the browsers (event_hub.hpp). The names and payloads of the events are in API.md.
//
// Thread safety: every method may be called from any thread. A job runs on a thread of its own;
// the destructor aborts a running job and waits for it.
#pragma once

#include "stampscan/acquisition/cell.hpp"
#include "stampscan/hmi/event_hub.hpp"
#include "stampscan/hmi/live_cloud.hpp"
#include "stampscan/jobs/calibrate_job.hpp"
#include "stampscan/jobs/scan_job.hpp"
#include "stampscan/jobs/verify_job.hpp"

#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <functional>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace stampscan::hmi {

// A part program the panel offers (acquisition/part_program.hpp).
struct ProgramSummary {
  std::string name, description, grid, material;
  double pitch_mm = 0, sheet_thickness_mm = 0;
  std::string note;  // e.g. "written on first use" for a virtual cell's own part not yet in the library
  std::optional<std::uint16_t> line_number;  // the number the line's PLC starts it by
  bool has_plan = true;  // false: not planned yet (a scan of it is refused until it is)
};

// What a scan of a program runs, prepared by the command that serves the cell: the program's plan
// (after the calibration scenes), its material and press program, and, on a virtual cell, the truth
// of the part it has put on the fixture.
struct ProgramScan {
  acquisition::ScanPlan plan;
  std::string material, press_program;
  jobs::PartProgramRef program;
  std::optional<jobs::SimulationTruth> truth;
};

// What a program's plan is predicted to see of its model's grid area (acquisition/part_planner.hpp),
// for the 3D view: samples of the grid area where the fixture holds the part (the machine frame, as
// the model's STL), each marked by the sensors that see it.
struct ProgramCoverage {
  double grid_area_mm2 = 0, spacing_mm = 0;
  double laser = 0, stereo = 0, either = 0;  // shares of the grid area
  std::size_t sweeps = 0, views = 0;         // the plan's part steps
  std::vector<float> xyz;                    // three per sample
  std::vector<std::uint8_t> seen;            // per sample: 1 the laser, 2 the cameras, 3 both, 0 neither
};

// The cell's part programs, as the command serving the cell reads them from its library. Empty
// functions: the panel offers none, and scans the setup's plan only.
struct CellPrograms {
  std::function<std::vector<ProgramSummary>()> list;
  // Throws naming what is wrong (an unknown name, a program that does not read).
  std::function<ProgramScan(const std::string& name)> prepare;
  // The program's nominal model as binary STL bytes, for the 3D view; throws like prepare.
  std::function<std::string(const std::string& name)> model_stl;
  // What the program's plan is predicted to see of its model; throws like prepare (and for a
  // program without a plan).
  std::function<ProgramCoverage(const std::string& name)> coverage;
  // Plans the program from its nominal model for the cell and makes the plan its own (as `station
  // plan NAME --into-program`); what the new plan is predicted to see. Throws like prepare.
  std::function<ProgramCoverage(const std::string& name)> plan;
  // Before a scan of the setup's own plan: a virtual cell puts its own part back on the fixture
  // (after a program's). May be empty.
  std::function<void()> restore;
  // The name of the program the line's PLC starts by this number (part_program.hpp's line_number);
  // nothing when none has it. Throws naming what is wrong. Empty: the line can start nothing.
  std::function<std::optional<std::string>(std::uint16_t line_number)> by_line_number;
};

// What the command prepares once for the cell it serves (the jobs fill in the rest per start).
struct CellSetup {
  acquisition::Cell* cell = nullptr;  // borrowed; alive while the jobs exist
  // Plan, run parameters, runs folder, truth; part id, program and material come with each start.
  jobs::ScanJobOptions scan;
  // The verification's sphere sweeps; absent: the cell offers no verify.
  std::optional<jobs::VerifyJobOptions> verify;
  // The calibration: its plan holds every calibration scene (sphere sweeps, plate views); each
  // request takes the scenes of the sensors it asks for. Absent: the cell offers no calibrate.
  std::optional<jobs::CalibrateJobOptions> calibrate;
  // digitizer.json in use and history/ of calibration records.
  std::filesystem::path calibration_dir = "stampscan-runs/calibration";
  CellPrograms programs;
  // The line's PLC may start scans (the cell file's [plc] line_start): the panel then watches the
  // handshake registers (line_handshake.hpp) while it serves.
  bool line_start = false;
};

// A part id a scan takes (from the panel or the line): letters, digits, '-', '_' and '.', not
// starting with '.'; it names the run's folder.
bool isPartId(const std::string& id);

struct ScanRequest {
  std::string part_id, program, material;
  std::string part_program;  // a program of the cell's library; empty: the setup's own plan
  bool by_line = false;      // started by the line's PLC (line_handshake.hpp), not by a person
};

struct JobStatus {
  bool busy = false;
  std::uint64_t job = 0;  // the running job's number (1, 2, ... since the panel started); 0 when idle
  std::string kind;      // "scan", "verify" or "calibrate" while busy
  std::string user;      // who started it
  bool by_line = false;  // a scan the line's PLC started
  std::string part_id;   // of a scan
  std::string run_id;    // once the scan has its folder
  std::string started_utc;
  bool measuring = false;  // a scan whose motion is over: measuring, fitting, the report
};

// How a job ended, for whoever started it (the line's handshake answers with it).
struct JobOutcome {
  enum class End {
    Verdict,     // measured whole: `verdict` holds the report's
    Refused,     // refused before anything moved (interlock, calibration, a device, a plan)
    Stopped,     // aborted on request or by a safety trip
    Failed,      // ended without a verdict (a device fault, the report failed, an error)
    Incomplete,  // measured, but lacking data the plan asked for: its verdict is not to be trusted
    Done,        // a verification or calibration that ran to its end
  };
  std::uint64_t job = 0;
  std::string kind;
  End end = End::Failed;
  std::optional<report::Verdict> verdict;  // a scan's, when it has a report
  std::string error;                       // why, for every end but Verdict and Done
};
const char* toString(JobOutcome::End end);

class CellJobs {
 public:
  CellJobs(CellSetup setup, EventHub& hub);
  ~CellJobs();
  CellJobs(const CellJobs&) = delete;
  CellJobs& operator=(const CellJobs&) = delete;

  // Connects the cell's devices in the background, so that the cell view shows them before the
  // first scan. A job started meanwhile waits for it.
  void connectDevices();
  // Nothing when started (and the job's number in *job when given); otherwise why not, in one line
  // (another job runs, no verify on this cell).
  std::optional<std::string> startScan(const ScanRequest& request, const std::string& user,
                                       std::uint64_t* job = nullptr);
  std::optional<std::string> startVerify(const std::string& user);
  // `sensors`: "digitizer", "cameras" or "all"; with `accept`, a calibration that fails its limits
  // is put in use anyway, recorded as accepted by `user`.
  std::optional<std::string> startCalibrate(const std::string& sensors, bool accept, const std::string& user);
  // Nothing when the running job is told to stop; otherwise why not (nothing runs, or the scan's
  // motion is over and only its measuring remains, which ends by itself).
  std::optional<std::string> abort(const std::string& reason);
  JobStatus status() const;
  // How job number `job` ended; nothing while it runs (or when it is older than the last few).
  std::optional<JobOutcome> outcomeOf(std::uint64_t job) const;
  // The cloud of the scan under way (or the last one), as it grows.
  const LiveCloud& liveCloud() const { return live_cloud_; }
  // The cell's calibration rules the jobs apply (validity, acceptance limits, the verification's
  // MPEs): the cell config's at first, then as maintenance sets them (cell_settings.hpp). A change
  // applies from the next job on; one under way keeps the rules it started with.
  acquisition::CalibrationPolicy calibrationPolicy() const;
  void setCalibrationPolicy(const acquisition::CalibrationPolicy& policy);
  // The setup's fields that no setting changes (the cell, the folders, what the cell offers); the
  // jobs' options are copied under the lock when a job starts.
  const CellSetup& setup() const { return setup_; }
  acquisition::Cell& cell() const { return *setup_.cell; }

 private:
  std::optional<std::string> begin(const std::string& kind, const std::string& user, const std::string& part_id);
  void runScan(ScanRequest request, std::string user);
  void runVerify(std::string user);
  void runCalibrate(jobs::CalibrateJobOptions options, std::string user);
  void finish(const std::string& event_json, JobOutcome outcome);

  CellSetup setup_;  // its options and policy change only under mutex_ (setCalibrationPolicy)
  EventHub& hub_;
  LiveCloud live_cloud_;
  std::mutex cell_mutex_;  // held by whoever drives the cell's devices: the connect, or a job
  mutable std::mutex mutex_;
  JobStatus status_;
  // The running job's abort (a scan, verify or calibrate job), set while its run() is under way.
  std::function<void(const std::string&)> abort_running_;
  // Registers a job's abort for as long as it lives (and hands it an abort asked before it existed).
  class RunningJob;
  std::optional<std::string> pending_abort_;
  std::uint64_t jobs_started_ = 0;
  std::deque<JobOutcome> outcomes_;  // the last few, newest last
  std::thread worker_, connector_;
};

// What to do about a fault of this kind, in words for the operator ("Close the cell door, then press
// Start again."); empty when there is no advice (FaultKind::Other).
std::string faultAdvice(acquisition::FaultKind kind);

}  // namespace stampscan::hmi
