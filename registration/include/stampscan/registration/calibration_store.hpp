// Calibration results as versioned JSON files: what was calibrated, when, from which data, with
// which residuals, on which cell and sensors. `station calibrate` puts them in use (the cell's
// calibration folder), `station process` writes them too, and both read them back when a trace holds
// no calibration scenes; `station scan` refuses one that is not for its cell and sensors, failed, or
// older than its validity (calibrationProblem).
//
//   digitizer.json  {"format": "stampscan-calibration", "version": 1, "kind": "digitizer",
//                    "created": "2026-11-22T03:00:00Z", "source": "...", "head_from_digitizer":
//                    {"rotation": [9, row-major], "translation_mm": [3]}, "latency_ns": ...,
//                    "residual_rms_mm": ..., "record": "<calibration record id>", "cell": "...",
//                    "sensors": [{"family", "model", "serial", "firmware"}], "verdict": "passed", ...}
//   cameras.json    intrinsics and distortion per camera, stereo extrinsics, head-to-left mount,
//                   reprojection errors.
#pragma once

#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/digitizer_calibration.hpp"

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::registration {

// Where a calibration in use came from: the record that put it in use, the cell and the sensors it
// was made with (cameras left, then right), and its verdict. Files written before these were kept
// have them empty, and a scan refuses them as of no known cell.
struct CalibrationProvenance {
  std::string record_id, cell;
  std::vector<SensorIdentity> sensors;
  std::string verdict;  // "passed" or "accepted": only those are put in use
  std::string accepted_by;
};

struct DigitizerCalibrationFile {
  DigitizerCalibration calibration;  // clock_offset_ns is not kept: it changes every power-up
  double residual_rms_mm = 0;
  std::size_t points = 0;
  std::string created, source;
  CalibrationProvenance provenance;
};

struct CameraCalibrationFile {
  StereoCalibration stereo;
  HandEyeResult head_from_left;
  std::string created, source;
  CalibrationProvenance provenance;
};

std::string utcNow();  // ISO 8601, seconds

// Writes atomically (temporary file, then rename). Throws naming the file on failure.
void saveDigitizerCalibration(const std::filesystem::path& file, const DigitizerCalibrationFile& c);
void saveCameraCalibration(const std::filesystem::path& file, const CameraCalibrationFile& c);
// The calibrations one source gave, written into `dir` as one set: digitizer.json and/or
// cameras.json replace the set that was there as a whole (a file the new set lacks is removed, so
// no new digitizer.json ends up beside an old cameras.json), and an interrupted write leaves the
// old set. Creates `dir` when missing. Throws naming the file on failure.
void saveCalibrationSet(const std::filesystem::path& dir, const DigitizerCalibrationFile* digitizer,
                        const CameraCalibrationFile* cameras);
// Puts calibrations in use in `dir`: the given files replace theirs together (an interrupted write
// leaves the old ones), and the other sensor's file is left as it is. Creates `dir` when missing.
void putCalibrationsInUse(const std::filesystem::path& dir, const DigitizerCalibrationFile* digitizer,
                          const CameraCalibrationFile* cameras);
// Throws std::runtime_error naming the file and the field that is missing or malformed.
DigitizerCalibrationFile loadDigitizerCalibration(const std::filesystem::path& file);
CameraCalibrationFile loadCameraCalibration(const std::filesystem::path& file);

// ISO 8601 UTC ("2026-11-24T09:15:00Z", as utcNow() writes) as a time; nothing when it is not such a text.
std::optional<std::chrono::system_clock::time_point> parseUtc(const std::string& text);

// What a stored calibration must match before a scan may measure with it.
struct CalibrationExpectation {
  std::string cell;                     // the cell config's name
  std::vector<SensorIdentity> sensors;  // the sensors that answer now, of the calibrated families
  double validity_days = 7;
  std::chrono::system_clock::time_point now = std::chrono::system_clock::now();
};
// Why the calibration in `file` (created at `created`) may not be used, in one line that names the
// file; nothing when it may. Refused: no known cell, another cell, a sensor of another serial (or
// missing), a verdict other than passed or accepted, a creation time that is unreadable, in the
// future, or older than the validity.
std::optional<std::string> calibrationProblem(const std::filesystem::path& file, const std::string& created,
                                              const CalibrationProvenance& provenance,
                                              const CalibrationExpectation& expected);

}  // namespace stampscan::registration
