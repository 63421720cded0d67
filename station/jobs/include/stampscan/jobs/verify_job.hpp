// The daily check of the cell's digitizer: what `station verify` does. Sweeps over the reference
// sphere (a plan of sphere sweeps only) are run on the cell by the ScanRunner into a trace in the
// calibration history, the profiles are placed in the machine frame with the calibration in use
// (or, without one, the calibration these sweeps give), and the probing form and size errors of
// ISO 10360-8 are computed on the sphere (registration/sphere_verification.hpp) and compared with
// their maximum permissible errors. The outcome is a calibration record beside its trace:
//
//   HISTORY/<id>.mcap   the sweeps, every device message as it arrived
//           <id>.json   the verification record (registration/calibration_record.hpp)
// and the record as a row of the results database (calibration_results.hpp).
//
// With a ball bar (a second sphere at a certified centre distance, swept too), the length
// measurement error E of ISO 10360-8: the distance between the two least-squares spheres' centres
// minus the certified one, against its MPE.
//
// With the cameras' calibration in use and views of the calibration plate in the plan, the stereo
// pair too (registration/stereo_verification.hpp): a passive stereo pair measures marks, which a
// plain sphere does not have, so its checks are the flat form error and the length error on the
// plate's dots at their certified pitch.
//
// Thread safety: run() blocks; abort() may be called from any other thread.
#pragma once

#include "stampscan/acquisition/cell.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/digitizer_calibration.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/registration/sphere_verification.hpp"
#include "stampscan/registration/stereo_verification.hpp"
#include "stampscan/jobs/traced_run.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace stampscan::jobs {

// The plan's sweeps over the reference sphere and the ball bar's second sphere, and its first
// `plate_views` views of the plate, named for verification. Throws std::runtime_error when the plan
// has no reference-sphere sweep.
acquisition::ScanPlan verificationStepsOf(const acquisition::ScanPlan& plan, std::size_t plate_views = 0);

struct VerifyJobOptions {
  acquisition::ScanPlan plan;      // sphere sweeps (other steps are refused)
  acquisition::ScanRunParams run;  // the session description must give the sphere's radius
  std::filesystem::path history = "stampscan-runs/calibration/history";
  // The calibration in use, and where it came from. Absent: the sweeps calibrate the digitizer
  // themselves, and the check then shows the sensor's noise and the calibration model's fit only.
  std::optional<registration::DigitizerCalibration> calibration;
  std::string calibration_source;
  // The certified diameter is taken from the session description (the cell's sphere).
  registration::SphereVerificationParams sphere;
  // The ball bar's second sphere and its certified distance from the reference sphere; the plan
  // must sweep it (acquisition::Scene::SecondSphere). Absent: no length check.
  struct BallBar {
    double second_diameter_mm = 25.4, distance_mm = 0, mpe_mm = 0.05;
  };
  std::optional<BallBar> ball_bar;
  // The cameras' calibration in use: the plan's plate views then check the stereo pair. Absent: no
  // stereo check (the plan must then have no views).
  std::optional<registration::CameraCalibrationFile> cameras;
  registration::StereoPlateParams stereo;
  // The results database the record also goes to as a row (calibration_results.hpp); "" for none.
  std::string results_database;
};

struct VerifyJobResult {
  acquisition::ScanRunResult run;
  registration::SphereVerification digitizer;
  // With a ball bar: the second sphere, the measured centre distance and the length error.
  std::optional<registration::SphereVerification> second_sphere;
  std::optional<double> distance_mm, length_error_mm;
  std::optional<registration::StereoPlateCheck> stereo;
  bool passed() const { return record.verdict == registration::RecordVerdict::Passed; }
  std::optional<registration::SphereCalibrationResult> calibrated;  // when the sweeps calibrated the digitizer
  registration::CalibrationRecord record;
  std::filesystem::path record_file, trace_file;
  std::string history_error;  // why the record is not a row of the results database ("" when it is)
};

// The verification as the cell file defines it: the MPEs of its [calibration], its ball bar's length
// check where it has one, the run's limits, and the records in `calibration_dir`'s history and
// results database. The plan, the session and the calibration in use are the caller's.
VerifyJobOptions cellVerification(const acquisition::CellConfig& config, const std::filesystem::path& calibration_dir);

// The cell's verification plan: the sphere sweeps of its calibration scenes (planned from `seed` as
// calibration plans them), the ball bar's too where the cell has one, and the first `plate_views`
// plate views.
acquisition::ScanPlan cellVerificationPlan(const acquisition::CellConfig& config, std::uint64_t seed,
                                           std::size_t plate_views = 0);

// The verification of the digitizer calibration in `file` (digitizer.json): sets the options'
// calibration and names its source. Throws std::runtime_error naming the file when it cannot be read.
void verifyWithCalibration(VerifyJobOptions& options, const std::filesystem::path& file);

class VerifyJob {
 public:
  VerifyJob(acquisition::Cell& cell, acquisition::ScanObserver* observer = nullptr);
  // Throws acquisition::ScanError for a plan refused before motion (nothing written), and
  // std::runtime_error for an aborted run (the trace is kept) or sweeps that do not measure the
  // sphere (too few points on it). A verification that fails its limits is a result, not an error.
  VerifyJobResult run(const VerifyJobOptions& options);
  void abort(const std::string& reason) { traced_.abort(reason); }

 private:
  acquisition::Cell& cell_;
  TracedRun traced_;
};

}  // namespace stampscan::jobs
