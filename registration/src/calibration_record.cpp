#include "stampscan/registration/calibration_record.hpp"

#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/registration/calibration_store.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <stdexcept>

namespace stampscan::registration {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kFormat = "stampscan-calibration-record";

json valuesJson(const std::vector<RecordValue>& values) {
  json a = json::array();
  for (const auto& v : values) {
    json value = {{"name", v.name}, {"value", v.value}, {"unit", v.unit}};
    if (v.uncertainty > 0) value["uncertainty"] = v.uncertainty;
    a.push_back(value);
  }
  return a;
}

json recordJson(const CalibrationRecord& r) {
  json sensors = json::array();
  for (const auto& s : r.sensors)
    sensors.push_back({{"family", s.family}, {"model", s.model}, {"serial", s.serial}, {"firmware", s.firmware}});
  json checks = json::array();
  for (const auto& c : r.checks)
    checks.push_back({{"name", c.name}, {"value", c.value}, {"limit", c.limit}, {"unit", c.unit}, {"passed", c.passed}});
  return {{"format", kFormat},
          {"version", CalibrationRecord::kVersion},
          {"id", r.id},
          {"kind", r.kind},
          {"created", r.created},
          {"cell", r.cell},
          {"sensors", sensors},
          {"traces", r.traces},
          {"calibration", r.calibration},
          {"parameters", valuesJson(r.parameters)},
          {"residuals", valuesJson(r.residuals)},
          {"checks", checks},
          {"verdict", toString(r.verdict)},
          {"accepted_by", r.accepted_by},
          {"notes", r.notes}};
}

// Field access that names the file and the field on failure.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}
  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw std::runtime_error(file_ + ": field '" + field + "' " + what);
  }
  const json& at(const json& j, const std::string& key, const std::string& where) const {
    const auto it = j.find(key);
    if (it == j.end()) fail(where + key, "is missing");
    return *it;
  }
  std::string text(const json& j, const std::string& key, const std::string& where = "") const {
    const json& v = at(j, key, where);
    if (!v.is_string()) fail(where + key, "is not text");
    return v.get<std::string>();
  }
  double number(const json& j, const std::string& key, const std::string& where = "") const {
    const json& v = at(j, key, where);
    if (!v.is_number()) fail(where + key, "is not a number");
    return v.get<double>();
  }
  const json& array(const json& j, const std::string& key) const {
    const json& v = at(j, key, "");
    if (!v.is_array()) fail(key, "is not a list");
    return v;
  }
  std::vector<std::string> texts(const json& j, const std::string& key) const {
    std::vector<std::string> out;
    const json& a = array(j, key);
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (!a[i].is_string()) fail(key + "[" + std::to_string(i) + "]", "is not text");
      out.push_back(a[i].get<std::string>());
    }
    return out;
  }
  std::vector<RecordValue> values(const json& j, const std::string& key) const {
    std::vector<RecordValue> out;
    const json& a = array(j, key);
    for (std::size_t i = 0; i < a.size(); ++i) {
      const std::string where = key + "[" + std::to_string(i) + "].";
      out.push_back({text(a[i], "name", where), number(a[i], "value", where), text(a[i], "unit", where),
                     a[i].contains("uncertainty") ? number(a[i], "uncertainty", where) : 0.0});
    }
    return out;
  }

 private:
  std::string file_;
};

RecordVerdict verdictFrom(const std::string& text, const Reader& reader) {
  for (const RecordVerdict v : {RecordVerdict::Passed, RecordVerdict::Failed, RecordVerdict::Accepted})
    if (text == toString(v)) return v;
  reader.fail("verdict", "is '" + text + "'; expected passed, failed or accepted");
}

// 20261124-091500 from utcNow()'s 2026-11-24T09:15:00Z: sorts by time, and names a file anywhere.
std::string utcStamp() {
  std::string stamp;
  for (const char c : utcNow())
    if (std::isdigit(static_cast<unsigned char>(c)))
      stamp.push_back(c);
    else if (c == 'T')
      stamp.push_back('-');
  return stamp;
}

}  // namespace

const char* toString(RecordVerdict verdict) {
  switch (verdict) {
    case RecordVerdict::Passed: return "passed";
    case RecordVerdict::Failed: return "failed";
    case RecordVerdict::Accepted: return "accepted";
  }
  return "failed";
}

const RecordValue* CalibrationRecord::parameter(const std::string& name) const {
  const auto it = std::find_if(parameters.begin(), parameters.end(), [&](const RecordValue& v) { return v.name == name; });
  return it == parameters.end() ? nullptr : &*it;
}

const RecordCheck* CalibrationRecord::check(const std::string& name) const {
  const auto it = std::find_if(checks.begin(), checks.end(), [&](const RecordCheck& c) { return c.name == name; });
  return it == checks.end() ? nullptr : &*it;
}

std::string newRecordId(const fs::path& history, const std::string& kind) {
  const std::string base = utcStamp() + "-" + kind;
  for (int k = 1;; ++k) {
    const std::string id = k == 1 ? base : base + "-" + std::to_string(k);
    // Neither a record nor a trace of that name (a calibration's trace is named like a record).
    if (!fs::exists(history / (id + ".json")) && !fs::exists(history / (id + ".mcap"))) return id;
  }
}

std::string calibrationRecordJson(const CalibrationRecord& record) { return recordJson(record).dump(2) + "\n"; }

fs::path saveCalibrationRecord(const fs::path& history, const CalibrationRecord& record) {
  if (record.id.empty() || record.kind.empty())
    throw std::invalid_argument("a calibration record needs an id and a kind before it is saved");
  if (record.id.find('/') != std::string::npos) throw std::invalid_argument("calibration record id '" + record.id + "' holds a '/'");
  std::error_code ec;
  fs::create_directories(history, ec);
  if (ec) throw std::runtime_error(history.string() + ": cannot create the calibration history folder: " + ec.message());
  const fs::path file = history / (record.id + ".json");
  fitting::writeFileAtomically(file, calibrationRecordJson(record));
  return file;
}

CalibrationRecord loadCalibrationRecord(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open the calibration record");
  json j;
  try {
    j = json::parse(in);
  } catch (const json::parse_error& e) {
    throw std::runtime_error(file.string() + ": not a calibration record (JSON does not parse at byte " +
                             std::to_string(e.byte) + ")");
  }
  const Reader r(file.string());
  if (!j.is_object()) throw std::runtime_error(file.string() + ": not a calibration record (not a JSON object)");
  if (const std::string format = r.text(j, "format"); format != kFormat)
    r.fail("format", "is '" + format + "'; expected '" + kFormat + "'");
  if (const double version = r.number(j, "version"); version != CalibrationRecord::kVersion)
    r.fail("version", "is " + std::to_string(static_cast<int>(version)) + "; this station reads version " +
                          std::to_string(CalibrationRecord::kVersion));
  CalibrationRecord out;
  out.id = r.text(j, "id");
  out.kind = r.text(j, "kind");
  out.created = r.text(j, "created");
  out.cell = r.text(j, "cell");
  const json& sensors = r.array(j, "sensors");
  for (std::size_t i = 0; i < sensors.size(); ++i) {
    const std::string where = "sensors[" + std::to_string(i) + "].";
    out.sensors.push_back({r.text(sensors[i], "family", where), r.text(sensors[i], "model", where),
                           r.text(sensors[i], "serial", where), r.text(sensors[i], "firmware", where)});
  }
  out.traces = r.texts(j, "traces");
  out.calibration = r.text(j, "calibration");
  out.parameters = r.values(j, "parameters");
  out.residuals = r.values(j, "residuals");
  const json& checks = r.array(j, "checks");
  for (std::size_t i = 0; i < checks.size(); ++i) {
    const std::string where = "checks[" + std::to_string(i) + "].";
    const json& passed = r.at(checks[i], "passed", where);
    if (!passed.is_boolean()) r.fail(where + "passed", "is not true or false");
    out.checks.push_back({r.text(checks[i], "name", where), r.number(checks[i], "value", where),
                          r.number(checks[i], "limit", where), r.text(checks[i], "unit", where), passed.get<bool>()});
  }
  out.verdict = verdictFrom(r.text(j, "verdict"), r);
  out.accepted_by = r.text(j, "accepted_by");
  out.notes = r.texts(j, "notes");
  if (out.id != file.stem().string())
    r.fail("id", "is '" + out.id + "' but the file is named for '" + file.stem().string() + "'");
  return out;
}

RecordListing listCalibrationRecords(const fs::path& history) {
  RecordListing out;
  std::error_code ec;
  if (!fs::is_directory(history, ec)) return out;
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(history))
    // <id>.json; <id>.calibration.json beside it is the calibration the record made, not a record.
    if (entry.is_regular_file() && entry.path().extension() == ".json" && entry.path().stem().extension() != ".calibration")
      files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    try {
      out.records.push_back(loadCalibrationRecord(f));
    } catch (const std::exception& e) {
      out.problems.push_back(e.what());
    }
  }
  return out;
}

CalibrationRecord findCalibrationRecord(const fs::path& history, const std::string& id) {
  const fs::path file = history / (id + ".json");
  if (id.empty() || id.find('/') != std::string::npos || !fs::exists(file))
    throw std::runtime_error("no calibration record '" + id + "' in " + history.string() +
                             " (`station calibration list` shows the records there)");
  return loadCalibrationRecord(file);
}

std::vector<RecordDifference> diffCalibrationRecords(const CalibrationRecord& before, const CalibrationRecord& after) {
  std::vector<RecordDifference> out;
  const auto text = [&](const std::string& name, const std::string& a, const std::string& b) {
    if (a != b) out.push_back({name, "", std::nullopt, std::nullopt, a, b});
  };
  text("kind", before.kind, after.kind);
  text("cell", before.cell, after.cell);
  text("calibration", before.calibration, after.calibration);
  text("verdict", toString(before.verdict), toString(after.verdict));
  // Sensors by family: a changed serial means another sensor, which a comparison must not hide.
  const auto sensorText = [](const CalibrationRecord& r, const std::string& family) {
    for (const auto& s : r.sensors)
      if (s.family == family) return s.model + " serial " + s.serial + " firmware " + s.firmware;
    return std::string("(none)");
  };
  std::vector<std::string> families;
  for (const auto* r : {&before, &after})
    for (const auto& s : r->sensors)
      if (std::find(families.begin(), families.end(), s.family) == families.end()) families.push_back(s.family);
  for (const auto& f : families) text("sensor " + f, sensorText(before, f), sensorText(after, f));

  // Named numbers: those of `before` in its order, then those only `after` has.
  const auto numbers = [&](const std::vector<std::pair<std::string, std::pair<double, std::string>>>& a,
                           const std::vector<std::pair<std::string, std::pair<double, std::string>>>& b) {
    for (const auto& [name, v] : a) {
      RecordDifference d{name, v.second, v.first, std::nullopt, "", ""};
      for (const auto& [bname, bv] : b)
        if (bname == name) d.after = bv.first;
      out.push_back(d);
    }
    for (const auto& [name, v] : b) {
      const bool in_a = std::any_of(a.begin(), a.end(), [&](const auto& x) { return x.first == name; });
      if (!in_a) out.push_back({name, v.second, std::nullopt, v.first, "", ""});
    }
  };
  const auto flatten = [](const CalibrationRecord& r) {
    std::vector<std::pair<std::string, std::pair<double, std::string>>> v;
    for (const auto& p : r.parameters) v.push_back({p.name, {p.value, p.unit}});
    for (const auto& p : r.residuals) v.push_back({p.name, {p.value, p.unit}});
    for (const auto& c : r.checks) v.push_back({c.name, {c.value, c.unit}});
    return v;
  };
  numbers(flatten(before), flatten(after));
  return out;
}

}  // namespace stampscan::registration
