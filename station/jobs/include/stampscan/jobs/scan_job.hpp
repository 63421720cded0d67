// A scan job: what `station scan`, the operator's panel and the line's PLC start. A plan on a cell
// into a run folder: the trace recorded live by the ScanRunner and, at the same time, measured as
// its steps complete (live_measurement.hpp: the calibrations after their scenes, each sweep while
// the next is scanned, the surface's shape fitted from the last part sweep on), then written with
// its run.json (station/run_folder/run_record.hpp), the forming-limit report and a row of the
// results history. A sensor the plan does not calibrate itself is measured with
// the calibration in use (`station calibrate`), checked against the cell and its sensors before
// anything moves. The command and the panel differ only in how they show progress (the observer)
// and how they abort (abort()).
//
//   RUNS/<UTC time>-<part id>/trace.mcap   every device message as it arrived
//                            cloud4d.ply   the grid elements with their strains, one per printed element
//                            measurements.ply every sweep's and view's measurement of them
//                            fitted.ply    the fitted surface, points 0.5 mm apart, with strain
//                            mesh.ply      the fitted surface as a mesh
//                            run.json      part id, plan, cell, devices, calibration used, counts, times,
//                                          outcome (and the accuracy against the truth when the cell is
//                                          simulated)
//                            report.pdf, report.html, fld.png, strain maps, elements.csv, report.json
//
// A plan or check refused before motion (acquisition::ScanError) leaves no run folder. An aborted
// run keeps its trace and a run.json saying why, and run() throws naming both.
#pragma once

#include "stampscan/report/run_report.hpp"
#include "stampscan/run_folder/run_record.hpp"
#include "stampscan/acquisition/cell.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/fitting/cloud.hpp"
#include "stampscan/registration/measure_scan.hpp"

#include <atomic>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

namespace stampscan::jobs {

// What the simulator knows of a virtual cell's scan, for the accuracy figures.
struct SimulationTruth {
  fitting::Cloud elements;                // the part's true grid elements
  std::int64_t digitizer_latency_ns = 0;  // the virtual digitizer's
  // Per element of `elements`: 1 when a sensor sees it whole from a pose of the plan
  // (sim/visibility.hpp); empty when not known.
  std::vector<std::uint8_t> visible{};
  // The part's true thickness strain at a point of its surface (machine frame); empty when not known.
  std::function<double(const fitting::Vec3& point)> thickness_strain_at{};
};

// The part program a scan runs (acquisition/part_program.hpp): its name (the part number) and folder.
struct PartProgramRef {
  std::string name;
  std::string folder;
};

// A scan stopped before its end: aborted on request (Ctrl-C, SIGTERM, the panel's Abort, the line) or
// by a safety trip (the kind says which). Its run folder keeps the trace (and what was measured),
// recorded as incomplete.
class ScanStopped : public acquisition::FaultError {
 public:
  ScanStopped(acquisition::FaultKind kind, const std::string& text) : FaultError(kind, text) {}
};

struct ScanJobOptions {
  acquisition::ScanPlan plan;
  acquisition::ScanRunParams run;  // the session description's cell geometry, limits
  std::string part_id = "part";
  std::filesystem::path runs_dir = "stampscan-runs";
  // The results database the run is recorded in: a runs folder or a PostgreSQL URL; "" for runs_dir's.
  std::string results_database;
  // When the cell is simulated: the job then reports its accuracy against the truth.
  std::optional<SimulationTruth> truth;
  // For the report written at the end (station/report): the sheet's material (empty: the report's
  // default) and the press program; both also go into run.json.
  std::string material, program;
  // The part program scanned, when the plan is a program's; recorded in run.json.
  std::optional<PartProgramRef> part_program;
  // Who started the scan, in words ("alice on the panel", "the line's PLC"); recorded in run.json
  // as "started_by" when given.
  std::string started_by;
  // The material library of the report: null for the built-in one (borrowed for run()).
  const report::MaterialLibrary* materials = nullptr;
  // The cell's calibration folder (digitizer.json and cameras.json in use, put there by `station
  // calibrate`) and the cell's rules for it. A sensor the plan calibrates itself (sphere sweeps for
  // the digitizer, plate views for the cameras) needs no stored calibration. For any other, the
  // stored one must exist, be for this cell and these sensors (serials), be accepted, and be within
  // its validity: otherwise the scan is refused before anything moves (acquisition::ScanError naming
  // `station calibrate`).
  std::filesystem::path calibration_dir = "stampscan-runs/calibration";
  acquisition::CalibrationPolicy calibration_policy;
  // A replay (sim/cell_replay.hpp): the trace it plays. The job then also measures that trace as
  // `station process` does and compares the two Cloud4Ds (ScanJobResult::against_recording).
  std::filesystem::path replayed_trace;
};

struct ScanAccuracy {
  std::size_t matched = 0;        // measured elements within 0.5 mm of a true one
  double position_rms_mm = 0, strain_rms = 0;
  // With the truth's visibility: the visible true elements, and those of them that a measured
  // element lies within 0.5 mm of (found); the true elements found that no sensor sees whole.
  std::size_t visible = 0, visible_found = 0, found_not_visible = 0;
  // Of the matched elements that state their strain's uncertainty (fitting::kStrainUncertainty),
  // the share whose true strain lies within the expanded uncertainty (k = 2): about 95 % when honest.
  std::size_t with_uncertainty = 0;
  double within_expanded_uncertainty = 0;
  // The matched elements split by the sensor whose measurement leads each (the Cloud4D's `source`):
  // where the error comes from when a session has both.
  run_folder::SensorAccuracyFigures laser, stereo;
};

struct ScanJobResult {
  std::filesystem::path run_dir;
  acquisition::ScanRunResult run;
  std::size_t elements = 0;      // printed elements in the Cloud4D
  std::size_t measurements = 0;  // the sweeps' and views' measurements they merge
  double measure_seconds = 0;     // from the end of the scan to the files written
  double cloud4d_seconds = 0;     // from the end of the scan to cloud4d.ply written (the fit comes after)
  registration::DigitizerCalibration digitizer;
  // Which calibration each sensor was measured with, in words (also in run.json as "calibration").
  std::string digitizer_calibration, camera_calibration;
  std::optional<double> sphere_residual_mm;
  std::optional<ScanAccuracy> accuracy;
  // The fitted surface's strain against the truth (when the cell is simulated and the surface was
  // fitted): where the map is read. As run.json's accuracy.surface_strain holds it.
  std::optional<run_folder::SurfaceStrainFigures> surface_accuracy;
  // With ScanJobOptions::replayed_trace: this run's measurements against the recording's.
  std::optional<ScanAccuracy> against_recording;
  std::size_t recording_measurements = 0;
  // What the scan did not record that the plan asked for (missing views, sweeps over the loss
  // limit): the result lacks elements there. Also in run.json as "data_loss".
  std::optional<std::string> data_loss;
  // The forming-limit report written into the run folder, or why it could not be.
  std::optional<report::ReportSummary> report;
  std::string report_error;
  // Why the run could not be recorded in the results history (empty: it was).
  std::string history_error;
};

// The data a finished run lacks, in one line, or nothing when it recorded all the plan asked for.
std::optional<std::string> dataLoss(const acquisition::ScanRunResult& r);

// What the plan predicted the part sweeps would see (SweepStep::expected_elements) against the
// laser's measurements (GridElement::view is the part sweep's index): a sweep that found under
// kShortSweep of its prediction, or all of them under kShortScan of theirs, did not measure the
// part it was planned to (a sensor, its timing or the machine's load); nothing when the plan
// predicts nothing or the scan found what it should.
inline constexpr double kShortSweep = 0.6, kShortScan = 0.85;
std::optional<std::string> measurementShortfall(const acquisition::ScanPlan& plan,
                                                const std::vector<registration::GridElement>& measurements);

class ScanJobObserver : public acquisition::ScanObserver, public registration::MeasureObserver {
 public:
  virtual void runFolder(const std::filesystem::path& /*dir*/) {}
  // The scan is over (completed or not); measuring begins if it completed.
  virtual void scanDone(const acquisition::ScanRunResult& /*run*/) {}
  void stageDone(std::string_view /*stage*/, const std::string& /*text*/) override {}
};

class ScanJob {
 public:
  ScanJob(acquisition::Cell& cell, ScanJobObserver* observer = nullptr);
  // Throws acquisition::ScanError when refused before motion (no folder is left), std::runtime_error
  // when the run was aborted (its folder keeps the trace and run.json) or measuring failed.
  ScanJobResult run(const ScanJobOptions& options);
  // Any thread: the run stops (motion aborted, shutter closed) and run() throws with the reason.
  // After the motion, the measurement stops at its next step (a view, a thirty-second of a fit
  // stage): the trace and what is measured are kept, and the run is recorded as incomplete.
  void abort(const std::string& reason);

 private:
  acquisition::Cell& cell_;
  ScanJobObserver* observer_;
  std::mutex mutex_;
  acquisition::ScanRunner* runner_ = nullptr;  // while a run is under way
  class LiveMeasurement* live_ = nullptr;        // while its measurement is
  std::optional<std::string> pending_abort_;

  // The plan on the cell, recorded into the trace file and fed to `live` as it comes.
  acquisition::ScanRunResult runOnCell(const acquisition::ScanPlan& plan, const acquisition::ScanRunParams& params,
                                       trace::TraceSink& live, acquisition::ScanObserver& observer,
                                       const std::filesystem::path& trace_file);
};

// Every measured element against the nearest true one; with `visible` (per true element, as
// SimulationTruth::visible), also how many of the visible true elements were found.
ScanAccuracy accuracyAgainst(const fitting::Cloud& measured, const fitting::Cloud& truth,
                             const std::vector<std::uint8_t>& visible = {});

// The fitted surface's strain against the truth: `elements` is the Cloud4D with the surface's
// strain at each element (fitting::kFittedStrain), `surface` the fitted points with their strain.
run_folder::SurfaceStrainFigures surfaceAccuracyAgainst(const fitting::Cloud& elements, const fitting::Cloud& surface,
                                             const SimulationTruth& truth);

}  // namespace stampscan::jobs
