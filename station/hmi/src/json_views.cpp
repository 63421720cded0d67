#include "json_views.hpp"

#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/jobs/calibration_status.hpp"

namespace stampscan::hmi {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json deviceJson(const drivers::Device& d) {
  const drivers::DeviceIdentity id = d.identity();
  json j = {{"name", d.name()},
            {"state", drivers::toString(d.state())},
            {"identity", {{"family", id.family}, {"vendor", id.vendor}, {"model", id.model}, {"serial", id.serial},
                          {"firmware", id.firmware}, {"address", id.address}}}};
  const auto faults = d.faults();
  if (!faults.empty()) j["last_fault"] = {{"code", faults.back().code}, {"text", faults.back().text}};
  return j;
}

json recordSummary(const registration::CalibrationRecord& r) {
  const json checks = checksJson(r.checks);
  return {{"id", r.id}, {"kind", r.kind}, {"created", r.created}, {"verdict", registration::toString(r.verdict)},
          {"calibration", r.calibration}, {"checks", checks}};
}

}  // namespace

json checksJson(const std::vector<registration::RecordCheck>& checks) {
  json out = json::array();
  for (const auto& c : checks)
    out.push_back({{"name", c.name}, {"value", c.value}, {"limit", c.limit}, {"unit", c.unit}, {"passed", c.passed}});
  return out;
}

json devicesJson(acquisition::Cell& cell) {
  return json::array({deviceJson(cell.cmm()), deviceJson(cell.plc()), deviceJson(cell.digitizer()),
                      deviceJson(cell.leftCamera()), deviceJson(cell.rightCamera())});
}

json calibrationJson(const fs::path& calibration_dir, const acquisition::CellConfig& cell) {
  json j;
  const fs::path stored = calibration_dir / "digitizer.json";
  std::error_code ec;
  if (fs::exists(stored, ec)) {
    try {
      const auto file = registration::loadDigitizerCalibration(stored);
      j["in_use"] = {{"file", stored.string()}, {"created", file.created}, {"source", file.source},
                     {"residual_rms_mm", file.residual_rms_mm}};
    } catch (const std::exception& e) {
      j["in_use"] = {{"file", stored.string()}, {"error", e.what()}};
    }
  } else {
    j["in_use"] = {{"file", ""}, {"note", "none stored: each scan calibrates the digitizer on its sphere sweeps"}};
  }
  const registration::RecordListing listing = registration::listCalibrationRecords(calibration_dir / "history");
  json last = nullptr, last_verification = nullptr;
  for (const auto& r : listing.records) {
    last = recordSummary(r);
    if (r.kind == "verification") last_verification = recordSummary(r);
  }
  j["last_record"] = last;
  j["last_verification"] = last_verification;
  j["verdict"] = last_verification.is_null() ? "not verified" : last_verification["verdict"].get<std::string>();
  j["records"] = listing.records.size();
  // Each sensor's calibration in use as a scan would judge it (station/calibration_status.hpp).
  json sensors = json::array();
  for (const jobs::SensorCalibrationStatus& s : jobs::calibrationStatus(calibration_dir, cell).sensors)
    sensors.push_back({{"sensor", s.sensor},
                       {"in_use", s.in_use},
                       {"usable", s.usable()},
                       {"record_id", s.record_id},
                       {"verdict", s.verdict},
                       {"created", s.created},
                       {"age_days", s.age_days},
                       {"valid_days", cell.calibration.validity_days},
                       {"problem", s.problem ? json(*s.problem) : json(nullptr)}});
  j["sensors"] = sensors;
  return j;
}

json cellJson(const CellJobs& jobs) {
  acquisition::Cell& cell = jobs.cell();
  json j = {{"name", cell.config().name}, {"devices", devicesJson(cell)}, {"job", statusJson(jobs.status())}};
  drivers::plc::ModbusPlc& plc = cell.plc();
  json plc_json = {{"connected", false}};
  const auto state = plc.state();
  if (state == drivers::DeviceState::Ready || state == drivers::DeviceState::Busy) {
    try {
      // The watchdog reads the inputs ten times a second; its last reading is as fresh as a new one.
      const drivers::plc::PlcInputs in = plc.lastInputs().value_or(plc.readInputs());
      const drivers::plc::PlcOutputs out = plc.readOutputs();
      plc_json = {{"connected", true},
                  {"interlocks", {{"door_closed", in.door_closed}, {"e_stop_ok", in.e_stop_chain_ok},
                                  {"light_curtain_clear", in.light_curtain_clear}, {"part_clamped", in.part_clamped},
                                  {"air_ok", in.air_pressure_ok}, {"shutter_closed", in.laser_shutter_closed},
                                  {"tripped", in.interlockTripped()}}},
                  {"stack_light", {{"green", out.stack_light_green}, {"amber", out.stack_light_amber},
                                   {"red", out.stack_light_red}}},
                  {"motion_enable", out.motion_enable},
                  {"fault_word", in.fault_word}};
    } catch (const std::exception& e) {
      plc_json = {{"connected", false}, {"error", e.what()}};
    }
  }
  j["plc"] = plc_json;
  j["calibration"] = calibrationJson(jobs.setup().calibration_dir, configInUse(jobs));
  return j;
}

acquisition::CellConfig configInUse(const CellJobs& jobs) {
  acquisition::CellConfig config = jobs.cell().config();
  config.calibration = jobs.calibrationPolicy();
  return config;
}

json runRowJson(const results::RunRow& r) {
  const auto opt = [](const auto& v) -> json { return v ? json(*v) : json(nullptr); };
  return {{"run_id", r.run_id},
          {"part_id", r.part_id},
          {"program", r.program},
          {"plan", r.plan},
          {"cell", r.cell},
          {"started_utc", r.started_utc},
          {"material", r.material},
          {"verdict", r.verdict},
          {"max_thinning_percent", opt(r.max_thinning_percent)},
          {"min_margin_percent", opt(r.min_margin_percent)},
          {"elements", opt(r.elements)},
          {"data_loss", r.data_loss},
          {"status", results::toString(r.status)},
          {"reason", r.reason}};
}

json statusJson(const JobStatus& s) {
  return {{"busy", s.busy},       {"kind", s.kind},       {"user", s.user},
          {"by_line", s.by_line}, {"part_id", s.part_id}, {"run_id", s.run_id},
          {"started_utc", s.started_utc}, {"measuring", s.measuring}};
}

json lineAnswerJson(const drivers::plc::CellAnswer& a) {
  return {{"ready", a.ready},
          {"busy", a.busy},
          {"done", a.done},
          {"verdict", std::string(drivers::plc::describe(a.verdict).name)},
          {"error", std::string(drivers::plc::describe(a.error).name)}};
}

json lineJson(const LineState& line) {
  json j = {{"connected", line.connected}, {"answer", lineAnswerJson(line.answer)}, {"last", line.last}};
  j["request"] = {{"start", line.request.start},
                  {"program_number", line.request.program_number},
                  {"part_id", line.request.part_id.value_or("")}};
  if (line.job) j["job"] = *line.job;
  if (!line.error.empty()) j["error"] = line.error;
  return j;
}

}  // namespace stampscan::hmi
