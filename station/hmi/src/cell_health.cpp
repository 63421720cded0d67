#include "stampscan/hmi/cell_health.hpp"

#include "json_views.hpp"
#include "stampscan/results/results_store.hpp"
#include "stampscan/jobs/calibration_status.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>

namespace stampscan::hmi {

namespace fs = std::filesystem;
using nlohmann::json;

const char* toString(HealthLevel level) {
  switch (level) {
    case HealthLevel::Ok: return "ok";
    case HealthLevel::Warning: return "warning";
    case HealthLevel::Fault: return "fault";
  }
  return "?";
}

namespace {

std::string format(const char* pattern, double a, double b = 0) {
  char text[256];
  std::snprintf(text, sizeof text, pattern, a, b);
  return text;
}

void add(CellHealth& h, std::string what, HealthLevel level, std::string text) {
  h.level = std::max(h.level, level);
  h.findings.push_back({std::move(what), level, std::move(text)});
}

void checkDevices(const CellJobs& jobs, CellHealth& h) {
  acquisition::Cell& cell = jobs.cell();
  const json devices = devicesJson(cell);
  h.detail["devices"] = devices;
  for (const json& d : devices) {
    const std::string state = d["state"].get<std::string>();
    if (state == "ready" || state == "busy") continue;
    std::string text = d["name"].get<std::string>() + " is " + state;
    if (d.contains("last_fault")) text += ": " + d["last_fault"]["text"].get<std::string>();
    add(h, d["name"].get<std::string>(), HealthLevel::Fault, text);
  }
}

void checkCalibration(const CellJobs& jobs, const HealthLimits& limits, CellHealth& h) {
  const acquisition::CellConfig config = configInUse(jobs);
  json sensors = json::array();
  for (const jobs::SensorCalibrationStatus& s : jobs::calibrationStatus(jobs.setup().calibration_dir, config).sensors) {
    json j = {{"sensor", s.sensor}, {"in_use", s.in_use}, {"usable", s.usable()}};
    // A file a scan would refuse (unreadable, another cell's, failed, expired) stops the scans.
    if (s.problem) {
      j["problem"] = *s.problem;
      add(h, "calibration of the " + s.sensor, HealthLevel::Fault,
          "the " + s.sensor + "'s calibration is not usable: " + *s.problem);
    }
    if (!s.in_use) {
      sensors.push_back(j);
      continue;  // none stored: the scans calibrate the digitizer themselves, or the cameras are not calibrated
    }
    const double hours_left = (config.calibration.validity_days - s.age_days) * 24;
    j["hours_left"] = hours_left;
    if (!s.problem && hours_left < limits.calibration_warning_hours)
      add(h, "calibration of the " + s.sensor, HealthLevel::Warning,
          "the " + s.sensor + "'s calibration expires in " + format("%.1f hours", hours_left) + ": calibrate it");
    sensors.push_back(j);
  }
  h.detail["calibration"] = sensors;
}

void checkDisk(const CellJobs& jobs, const HealthLimits& limits, CellHealth& h) {
  const fs::path runs = jobs.setup().scan.runs_dir;
  std::error_code ec;
  fs::path probe = runs;
  while (!probe.empty() && !fs::exists(probe, ec)) probe = probe.parent_path();  // not made yet: its parent's disk
  const fs::space_info space = fs::space(probe.empty() ? fs::path(".") : probe, ec);
  if (ec) {
    add(h, "disk", HealthLevel::Fault, "the runs folder " + runs.string() + " cannot be examined: " + ec.message());
    return;
  }
  const double share = space.capacity > 0 ? static_cast<double>(space.available) / static_cast<double>(space.capacity) : 0;
  h.detail["disk"] = {{"runs_dir", runs.string()}, {"available_bytes", space.available},
                      {"capacity_bytes", space.capacity}, {"available_share", share}};
  const double gib = static_cast<double>(space.available) / (1u << 30);
  if (space.available < limits.disk_fault_bytes)
    add(h, "disk", HealthLevel::Fault, format("the runs' disk is full: %.2f GiB free, less than a scan needs", gib));
  else if (space.available < limits.disk_warning_bytes || share < limits.disk_warning_share)
    add(h, "disk", HealthLevel::Warning,
        format("the runs' disk is nearly full: %.1f GiB free (%.1f %%); move old runs away", gib, 100 * share));
}

void checkDatabase(const CellJobs& jobs, CellHealth& h) {
  const std::string database = jobs.setup().scan.results_database.empty() ? jobs.setup().scan.runs_dir.string()
                                                                          : jobs.setup().scan.results_database;
  json j = {{"location", results::locationForMessages(database)}};  // never its password
  const bool sqlite = !results::isDatabaseUrl(database);
  std::error_code ec;
  if (sqlite && !fs::exists(fs::path(database) / results::kSqliteFileName, ec)) {
    j["reachable"] = true;
    j["note"] = "not made yet: the first run makes it";
  } else {
    try {
      results::StoreOptions options;
      options.read_only = true;
      const auto store = results::openResultsStore(database, options);
      j["schema_version"] = store->schemaVersion();
      j["reachable"] = true;
    } catch (const std::exception& e) {
      j["reachable"] = false;
      j["error"] = e.what();
      add(h, "database", HealthLevel::Fault, std::string("the results database cannot be read: ") + e.what());
    }
  }
  h.detail["database"] = j;
}

}  // namespace

CellHealth cellHealth(const CellJobs& jobs, const HealthLimits& limits) {
  CellHealth h;
  h.detail = json::object();
  checkDevices(jobs, h);
  checkCalibration(jobs, limits, h);
  checkDisk(jobs, limits, h);
  checkDatabase(jobs, h);
  return h;
}

json healthJson(const CellHealth& health, bool with_detail) {
  json findings = json::array();
  for (const HealthFinding& f : health.findings)
    findings.push_back({{"what", f.what}, {"level", toString(f.level)}, {"text", f.text}});
  json j = with_detail ? health.detail : json::object();
  j["status"] = toString(health.level);
  j["findings"] = findings;
  return j;
}

}  // namespace stampscan::hmi
