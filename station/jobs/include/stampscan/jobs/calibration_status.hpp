// The calibration in use, sensor by sensor, as a scan would judge it before anything moves (the
// cell, the verdict, the age against the validity; the serials are compared by the scan, which has
// the sensors): for `station calibration status` and the panel's maintenance view.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/registration/calibration_record.hpp"

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::jobs {

struct SensorCalibrationStatus {
  std::string sensor;              // "digitizer", "cameras"
  bool in_use = false;             // a file is there and reads
  std::string record_id, verdict, created;
  double age_days = 0;
  // Why a scan would refuse the file (unreadable, another cell's, failed, expired); nothing when it
  // would take it, or when there is no file (in_use false).
  std::optional<std::string> problem;
  bool usable() const { return in_use && !problem; }
};

struct CalibrationStatus {
  std::vector<SensorCalibrationStatus> sensors;          // the digitizer, then the cameras
  std::optional<registration::CalibrationRecord> last_verification;
  bool allUsable() const;
};

CalibrationStatus calibrationStatus(const std::filesystem::path& calibration_dir, const acquisition::CellConfig& cell,
                                    std::chrono::system_clock::time_point now = std::chrono::system_clock::now());

}  // namespace stampscan::jobs
