#include "stampscan/jobs/calibration_status.hpp"

#include "stampscan/registration/calibration_store.hpp"

#include <algorithm>

namespace stampscan::jobs {

namespace fs = std::filesystem;

bool CalibrationStatus::allUsable() const {
  return std::all_of(sensors.begin(), sensors.end(), [](const SensorCalibrationStatus& s) { return s.usable(); });
}

CalibrationStatus calibrationStatus(const fs::path& dir, const acquisition::CellConfig& cell,
                                    std::chrono::system_clock::time_point now) {
  CalibrationStatus out;
  for (const char* sensor : {"digitizer", "cameras"}) {
    SensorCalibrationStatus& s = out.sensors.emplace_back();
    s.sensor = sensor;
    const fs::path file = dir / (s.sensor + ".json");
    if (!fs::exists(file)) continue;  // none in use
    std::string created;
    registration::CalibrationProvenance provenance;
    try {
      if (s.sensor == "digitizer") {
        const auto d = registration::loadDigitizerCalibration(file);
        created = d.created, provenance = d.provenance;
      } else {
        const auto c = registration::loadCameraCalibration(file);
        created = c.created, provenance = c.provenance;
      }
    } catch (const std::exception& e) {
      s.problem = e.what();
      continue;
    }
    s.in_use = true;
    s.record_id = provenance.record_id;
    s.verdict = provenance.verdict;
    s.created = created;
    if (const auto when = registration::parseUtc(created))
      s.age_days = std::chrono::duration<double>(now - *when).count() / 86400.0;
    registration::CalibrationExpectation expected;
    expected.cell = cell.name;
    expected.sensors = provenance.sensors;  // the serials are the scan's to compare, with the sensors at hand
    expected.validity_days = cell.calibration.validity_days;
    expected.now = now;
    s.problem = registration::calibrationProblem(file, created, provenance, expected);
  }
  for (auto& r : registration::listCalibrationRecords(dir / "history").records)
    if (r.kind == "verification") out.last_verification = std::move(r);
  return out;
}

}  // namespace stampscan::jobs
