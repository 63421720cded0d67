// Calibration on the cell: what `station calibrate` does. The calibration scenes of a plan (sweeps
// over the reference sphere for the digitizer's mount and latency, views of the plate for the
// cameras, the stereo pair and the left camera's mount on the head) are run on the cell into a
// trace in the calibration history, then:
//
//   1. each sensor is calibrated on them (registration/digitizer_calibration.hpp,
//      calibrateCameraRig in registration/measure_scan.hpp);
//   2. views that spoil a fit are named and left out, and the fit made again without them: a plate
//      view the plate is not found in or whose reprojection error stands out (calibrateCamera's
//      rule), a sphere sweep with few points on the sphere (the sphere mostly out of the fan) or
//      whose points stand off the fitted sphere;
//   3. every estimated parameter gets its standard uncertainty: the jackknife over the sweeps (the
//      digitizer) and over the views (the hand-eye mount, the baseline), the fit's Jacobian for the
//      intrinsics;
//   4. the residuals are checked against the cell's acceptance limits (acquisition::CalibrationPolicy)
//      and the parameters compared with the calibration in use, with a change beyond the drift
//      limits reported as drift;
//   5. a calibration whose checks all pass (or that an engineer accepts, named in the record) is put
//      in use: <dir>/digitizer.json or cameras.json is replaced, the other sensor's file is left as
//      it is, and the replaced one stays in the history. A failed one is recorded and not used.
//
//   DIR/digitizer.json, cameras.json           the calibration in use (registration/calibration_store.hpp)
//   DIR/history/<time>-calibration.mcap        the calibration scenes, every device message as it arrived
//   DIR/history/<id>.json                      one record per sensor (registration/calibration_record.hpp)
//   DIR/history/<id>.calibration.json          the calibration that record made, whether used or not
//   and each record as a row of the results database (calibration_results.hpp).
//
// Thread safety: run() blocks; abort() may be called from any other thread.
#pragma once

#include "stampscan/acquisition/cell.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/jobs/traced_run.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::jobs {

// The cell's calibration folder: `option` when given, else the cell config's [calibration] dir,
// else <runs>/calibration (beside the run folders of `station scan -o RUNS`).
std::filesystem::path calibrationFolder(const std::string& option, const acquisition::CalibrationPolicy& policy,
                                        const std::filesystem::path& runs = "stampscan-runs");

// The plan's calibration scenes alone (sphere sweeps when `digitizer`, plate views when `cameras`),
// named for calibration. Throws std::runtime_error when the plan has none of the asked-for scenes.
acquisition::ScanPlan calibrationScenesOf(const acquisition::ScanPlan& plan, bool digitizer, bool cameras);

struct CalibrateJobOptions {
  acquisition::ScanPlan plan;      // sphere sweeps and/or plate views (other steps are refused)
  acquisition::ScanRunParams run;  // the session description must give the sphere and the plate
  std::filesystem::path calibration_dir = "stampscan-runs/calibration";
  acquisition::CalibrationPolicy policy;  // acceptance and drift limits
  bool digitizer = true, cameras = true;  // which sensors to calibrate
  // Not empty: a calibration that fails a check is put in use anyway, recorded as accepted by them.
  std::string accepted_by;
  // The results database the records also go to as rows (calibration_results.hpp); "" for none.
  std::string results_database;
};

// The calibration of the sensors asked for as the cell file defines it: its acceptance and drift
// limits, the run's limits, and `calibration_dir` with its results database. The plan and the
// session are the caller's.
CalibrateJobOptions cellCalibration(const acquisition::CellConfig& config, const std::filesystem::path& calibration_dir,
                                    bool digitizer = true, bool cameras = true);

// The cell's calibration plan: its calibration scenes ([calibration] sphere_sweeps, plate_views,
// planned from `seed` for its artefacts), those of the sensors asked for.
acquisition::ScanPlan cellCalibrationPlan(const acquisition::CellConfig& config, std::uint64_t seed,
                                          bool digitizer = true, bool cameras = true);

struct SensorCalibration {
  registration::CalibrationRecord record;
  std::filesystem::path record_file;
  bool in_use = false;                 // put in use (passed, or accepted)
  std::vector<std::string> left_out;   // views or sweeps that spoiled the fit, each with why
  std::vector<std::string> drift;      // changes against the calibration in use beyond the drift limits
  std::string previous;                // the calibration in use before (record id), "" when none
};

struct CalibrateJobResult {
  acquisition::ScanRunResult run;
  std::filesystem::path trace_file;
  std::optional<SensorCalibration> digitizer, cameras;
  std::optional<registration::DigitizerCalibrationFile> digitizer_file;  // what was calibrated
  std::optional<registration::CameraCalibrationFile> cameras_file;
  std::string history_error;  // why the records are not rows of the results database ("" when they are)
};

class CalibrateJob {
 public:
  CalibrateJob(acquisition::Cell& cell, acquisition::ScanObserver* observer = nullptr);
  // Throws acquisition::ScanError for a plan refused before motion (nothing written), and
  // std::runtime_error for an aborted run (the trace is kept) or scenes that do not calibrate a
  // sensor at all (too few views or points). A calibration that fails its limits is a result.
  CalibrateJobResult run(const CalibrateJobOptions& options);
  void abort(const std::string& reason) { traced_.abort(reason); }

 private:
  acquisition::Cell& cell_;
  TracedRun traced_;
};

}  // namespace stampscan::jobs
