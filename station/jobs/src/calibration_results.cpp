#include "stampscan/jobs/calibration_results.hpp"

#include "stampscan/results/results_store.hpp"

namespace stampscan::jobs {

std::string calibrationResultsDatabase(const std::string& configured, const std::filesystem::path& calibration_dir) {
  if (!configured.empty()) return configured;
  const std::filesystem::path parent = std::filesystem::absolute(calibration_dir).lexically_normal().parent_path();
  return parent.string();
}

std::string recordCalibrationInResults(const registration::CalibrationRecord& r, const std::filesystem::path& record_file,
                                       const std::string& database) {
  results::CalibrationRow row;
  row.record_id = r.id;
  row.kind = r.kind;
  row.created_utc = r.created;
  row.cell = r.cell;
  row.verdict = registration::toString(r.verdict);
  row.accepted_by = r.accepted_by;
  std::size_t passed = 0;
  for (const auto& c : r.checks) passed += c.passed ? 1 : 0;
  row.summary = std::to_string(passed) + " of " + std::to_string(r.checks.size()) + " checks passed";
  for (const auto& c : r.checks)
    if (!c.passed) row.summary += "; failed: " + c.name;
  row.record_file = record_file.string();
  row.record_json = registration::calibrationRecordJson(r);
  try {
    results::openResultsStore(database)->recordCalibration(row);
    return {};
  } catch (const std::exception& e) {
    return e.what();
  }
}

}  // namespace stampscan::jobs
