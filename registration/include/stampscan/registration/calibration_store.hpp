// Calibration results as versioned JSON files: what was calibrated, when, from which data, with
// which residuals. `station process` writes them and reads them back when a trace holds no
// calibration scenes.
//
//   digitizer.json  {"format": "stampscan-calibration", "version": 1, "kind": "digitizer",
//                    "created": "2026-11-22T03:00:00Z", "source": "...", "head_from_digitizer":
//                    {"rotation": [9, row-major], "translation_mm": [3]}, "latency_ns": ...,
//                    "residual_rms_mm": ..., ...}
//   cameras.json    intrinsics and distortion per camera, stereo extrinsics, head-to-left mount,
//                   reprojection errors.
#pragma once

#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/digitizer_calibration.hpp"

#include <filesystem>
#include <string>

namespace stampscan::registration {

struct DigitizerCalibrationFile {
  DigitizerCalibration calibration;  // clock_offset_ns is not kept: it changes every power-up
  double residual_rms_mm = 0;
  std::size_t points = 0;
  std::string created, source;
};

struct CameraCalibrationFile {
  StereoCalibration stereo;
  HandEyeResult head_from_left;
  std::string created, source;
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
// Throws std::runtime_error naming the file and the field that is missing or malformed.
DigitizerCalibrationFile loadDigitizerCalibration(const std::filesystem::path& file);

}  // namespace stampscan::registration
