// run.json: what a scan's run folder says of the scan beside its data files. One typed record,
// written by the scan job (station/jobs) and read by the report, the results history and the
// panel; this header is its only definition, and run_record.cpp its only encoding.
//
// The file is JSON (an object); each member below is written under its own name, sections as
// nested objects. Reading is lenient with what is missing (a run written by an older station, a
// run aborted before it was measured: its sections are absent) and strict with what is there: a
// member of the wrong type is refused, naming the file and the member ("RUN/run.json:
// measurement.elements: expected a whole number, found a text"). Members this station does not know
// are ignored.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace stampscan::run_folder {

// A run.json that cannot be read: not JSON, not an object, or a member of the wrong type.
class RunRecordError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A device as the scan found it (its identity answer).
struct DeviceRecord {
  std::string family, model, serial, firmware;
  bool operator==(const DeviceRecord&) const = default;
};

// Where the scan's wall time went beyond moving (acquisition::ScanRunResult::spent).
struct TimeSpent {
  double moving = 0, settling = 0, waiting_for_frames = 0, clock_sync = 0, digitizer_start_drain_stop = 0, other = 0;
  bool operator==(const TimeSpent&) const = default;
};

// "scan": what the cell did.
struct ScanFigures {
  std::int64_t sweeps = 0;
  double wall_seconds = 0, motion_seconds = 0;
  std::int64_t profiles = 0, lost_profiles = 0, sweeps_repeated = 0, sweeps_over_loss_limit = 0;
  std::int64_t stereo_views = 0, stereo_views_missing = 0, positions = 0;
  TimeSpent spent_seconds;
  bool operator==(const ScanFigures&) const = default;
};

// "fixture": where the part's datum frame lies on the table. The clouds, the surface and the maps
// are in the machine frame.
struct FixtureRecord {
  std::string name;
  std::array<double, 3> datum_mm{}, datum_rotation_deg{};
  bool operator==(const FixtureRecord&) const = default;
};

// "calibration": which calibration each sensor was measured with, in words.
struct CalibrationUsed {
  std::string digitizer, cameras;
  bool operator==(const CalibrationUsed&) const = default;
};

// One measurement's standard uncertainty on one sensor path, and its part shared by the path's
// measurements of one element (registration/element_merge.hpp), as the scan's twins showed them.
struct PathUncertainty {
  double strain = 0;
  std::optional<double> strain_shared;
  double position_mm = 0;
  std::optional<double> position_shared_mm;
  std::int64_t twin_pairs = 0;
  bool operator==(const PathUncertainty&) const = default;
};

// "measurement.surface": the fitted surface (absent when the elements' own surface was fitted).
struct SurfaceFigures {
  std::int64_t laser_returns = 0, points = 0, points_without_strain = 0, mesh_triangles = 0;
  double shape_bandwidth_median_mm = 0, strain_bandwidth_median_mm = 0, seconds = 0;
  bool operator==(const SurfaceFigures&) const = default;
};

// "measurement": what was measured and how fast.
struct MeasurementFigures {
  std::int64_t elements = 0;      // printed elements (the Cloud4D's points)
  std::int64_t measurements = 0;  // every sweep's and view's measurements of them
  double seconds_after_scan = 0, cloud4d_seconds_after_scan = 0;
  double digitizer_latency_ms = 0;
  std::optional<PathUncertainty> laser_uncertainty, stereo_uncertainty;  // "uncertainty": {"laser", "stereo"}
  std::optional<double> sphere_residual_mm;  // when the digitizer was calibrated in the run
  std::optional<SurfaceFigures> surface;
  bool operator==(const MeasurementFigures&) const = default;
};

// "accuracy.visible": the true elements a sensor sees whole from a pose of the plan.
struct VisibleFigures {
  std::int64_t elements = 0, found = 0, found_not_visible = 0;
  bool operator==(const VisibleFigures&) const = default;
};

// "accuracy.surface_strain": the fitted surface's strain against the truth.
struct SurfaceStrainFigures {
  std::int64_t elements = 0;
  double at_elements_rms = 0, elements_own_rms = 0;
  std::int64_t between_points = 0;
  double between_rms = 0;
  std::int64_t within_grid_points = 0, within_grid_without_strain = 0;
  bool operator==(const SurfaceStrainFigures&) const = default;
};

// "accuracy.by_sensor.laser" / ".stereo": the matched elements whose leading measurement (the
// Cloud4D's `source`) is that sensor's, against the truth.
struct SensorAccuracyFigures {
  std::int64_t matched = 0;
  double position_rms_mm = 0, strain_rms = 0;
  bool operator==(const SensorAccuracyFigures&) const = default;
};

// "accuracy": the scan against the simulator's truth (a virtual cell only).
struct AccuracyFigures {
  std::int64_t matched = 0;
  double position_rms_mm = 0, strain_rms = 0;
  double strain_within_expanded_uncertainty = 0;  // the share (0..1) of true strains within k = 2
  double true_latency_ms = 0;
  std::optional<VisibleFigures> visible;
  std::optional<SurfaceStrainFigures> surface_strain;
  std::optional<SensorAccuracyFigures> laser_led, stereo_led;  // "by_sensor": where the error comes from
  bool operator==(const AccuracyFigures&) const = default;
};

// "replay": a replayed trace measured as `station process` measures it, against this run.
struct ReplayFigures {
  std::string recording;
  std::int64_t reference_measurements = 0, matched = 0;
  double position_rms_mm = 0, strain_rms = 0;
  bool operator==(const ReplayFigures&) const = default;
};

// "part_program": the program scanned, when the plan was a program's.
struct PartProgramUsed {
  std::string name, folder;
  bool operator==(const PartProgramUsed&) const = default;
};

struct RunRecord {
  std::string part_id, plan, cell;
  std::string trace = "trace.mcap";  // the trace's file name in the folder
  bool completed = true;
  std::string abort_reason;  // why the scan stopped early ("" when completed)
  std::string started_by;    // who started the scan, in words ("" when not said)
  std::vector<std::string> safety_events;
  std::vector<DeviceRecord> devices;
  FixtureRecord fixture;
  std::optional<CalibrationUsed> calibration;
  std::optional<ScanFigures> scan;
  std::optional<MeasurementFigures> measurement;
  std::optional<AccuracyFigures> accuracy;
  std::optional<ReplayFigures> replay;
  std::string data_loss;       // what the scan lacks that its plan asked for; "" when nothing
  std::string material;        // the sheet's material, when the scan was given one
  std::string program;         // the press program, when given
  std::optional<PartProgramUsed> part_program;
  bool operator==(const RunRecord&) const = default;
};

// The file's name in a run folder.
inline constexpr const char* kRunRecordFile = "run.json";

// The record as run.json holds it.
nlohmann::json toJson(const RunRecord& record);
// Throws RunRecordError naming `where` (the file) and the member when a member has the wrong type.
RunRecord runRecordFromJson(const nlohmann::json& json, const std::string& where);

// Writes RUN_DIR/run.json whole or not at all (fitting/atomic_file.hpp).
void writeRunRecord(const std::filesystem::path& run_dir, const RunRecord& record);
// RUN_DIR/run.json; nothing when the folder has none. Throws RunRecordError when it is unreadable or
// damaged (naming the file and what is wrong).
std::optional<RunRecord> readRunRecord(const std::filesystem::path& run_dir);

}  // namespace stampscan::run_folder
