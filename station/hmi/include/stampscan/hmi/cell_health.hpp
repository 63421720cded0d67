// The cell's health for the plant's monitoring (GET /api/health) and the panel's warnings: the
// devices, the calibration's validity, the runs' disk and the results database. Each finding is
// fine, a warning (the cell works, someone should act soon: a calibration that expires within a
// day, a disk nearly full) or a fault (the cell cannot scan: a device down, the database
// unreachable, the disk full).
#pragma once

#include "stampscan/hmi/cell_jobs.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace stampscan::hmi {

enum class HealthLevel { Ok, Warning, Fault };
const char* toString(HealthLevel level);

struct HealthFinding {
  std::string what;  // "disk", "calibration of the digitizer", "database", a device's name
  HealthLevel level = HealthLevel::Ok;
  std::string text;  // what was found, in a sentence
};

struct CellHealth {
  HealthLevel level = HealthLevel::Ok;  // the worst of the findings
  std::vector<HealthFinding> findings;
  nlohmann::json detail;  // the figures behind them (free bytes, hours left, device states)
};

// What counts as a nearly full disk: less free than this many bytes or this share of it.
struct HealthLimits {
  std::uint64_t disk_warning_bytes = 2ull << 30;
  double disk_warning_share = 0.05;
  std::uint64_t disk_fault_bytes = 200ull << 20;  // less than a whole-part scan's trace
  double calibration_warning_hours = 24;
};

CellHealth cellHealth(const CellJobs& jobs, const HealthLimits& limits = {});
// The status and the findings; with the detail, also the figures (devices' identities, paths):
// those only for a caller with a session.
nlohmann::json healthJson(const CellHealth& health, bool with_detail);

}  // namespace stampscan::hmi
