// The calibration history: one versioned record per calibration or verification run on the cell,
// kept as a JSON file per record in a history folder (until the cell's results database holds
// them, with the same content). A record says what was done, when, on which cell and sensors,
// from which traces, what came out (parameters, residuals, the checks against their limits) and the
// verdict, with who accepted it when an engineer overrode a failed check.
//
//   HISTORY/<id>.json   {"format": "stampscan-calibration-record", "version": 1,
//                        "id": "20261124-091500-verification", "kind": "verification",
//                        "created": "2026-11-24T09:15:00Z", "cell": "virtual cell",
//                        "sensors": [{"family": "digitizer", "model": ..., "serial": ..., "firmware": ...}],
//                        "traces": ["20261124-091500-verification.mcap"],
//                        "calibration": "what the run used or produced, in words",
//                        "parameters": [{"name": ..., "value": ..., "unit": ..., "uncertainty": ...}],
//                        "residuals":  [{"name": ..., "value": ..., "unit": ...}],
//                        "checks": [{"name": ..., "value": ..., "limit": ..., "unit": ..., "passed": true}],
//                        "verdict": "passed" | "failed" | "accepted", "accepted_by": "", "notes": [...]}
//
// Values are named numbers with their units, so that list, show and diff treat every kind of
// record alike. Thread safety: the functions touch only their arguments and the files named.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::registration {

struct RecordValue {
  std::string name;  // e.g. "digitizer latency", "sphere centre x"
  double value = 0;
  std::string unit;  // "mm", "ms", "px", "" for a count
  double uncertainty = 0;  // standard uncertainty, in the unit; 0 when not estimated
  bool operator==(const RecordValue&) const = default;
};

// A figure compared with its limit: passes when |value| <= limit (a probing size error may be
// negative; a form error or a residual is not).
struct RecordCheck {
  std::string name;  // e.g. "probing form error P[Form.Sph.All] (digitizer)"
  double value = 0, limit = 0;
  std::string unit;
  bool passed = false;
  bool operator==(const RecordCheck&) const = default;
};

struct SensorIdentity {
  std::string family, model, serial, firmware;
  bool operator==(const SensorIdentity&) const = default;
};

enum class RecordVerdict {
  Passed,    // every check within its limit
  Failed,    // a check outside its limit, not accepted
  Accepted,  // a check outside its limit, accepted by an engineer (accepted_by names them)
};
const char* toString(RecordVerdict verdict);

struct CalibrationRecord {
  static constexpr int kVersion = 1;
  std::string id;       // unique in its history folder; sorts by time
  std::string kind;     // "verification", "digitizer", "cameras"
  std::string created;  // ISO 8601 UTC
  std::string cell;     // the cell config's name
  std::vector<SensorIdentity> sensors;
  std::vector<std::string> traces;  // file names, relative to the history folder
  std::string calibration;          // which calibration the run used or produced
  std::vector<RecordValue> parameters, residuals;
  std::vector<RecordCheck> checks;
  RecordVerdict verdict = RecordVerdict::Failed;
  std::string accepted_by;  // set only with RecordVerdict::Accepted
  std::vector<std::string> notes;

  const RecordValue* parameter(const std::string& name) const;
  const RecordCheck* check(const std::string& name) const;
  bool operator==(const CalibrationRecord&) const = default;
};

// A fresh record id for `kind` in `history`: the UTC time and the kind ("20261124-091500-verification"),
// with "-2", "-3", ... when a record or a trace of that name exists.
std::string newRecordId(const std::filesystem::path& history, const std::string& kind);

// The record as its file holds it (JSON text), for a database that keeps it whole.
std::string calibrationRecordJson(const CalibrationRecord& record);

// Writes <history>/<id>.json atomically, creating the folder. Throws std::invalid_argument for a
// record without id or kind, std::runtime_error naming the file when it cannot be written.
std::filesystem::path saveCalibrationRecord(const std::filesystem::path& history, const CalibrationRecord& record);

// Throws std::runtime_error naming the file and the field that is missing or malformed, or the
// format or version it does not know.
CalibrationRecord loadCalibrationRecord(const std::filesystem::path& file);

struct RecordListing {
  std::vector<CalibrationRecord> records;  // by id, oldest first
  std::vector<std::string> problems;       // one line per file that is not a readable record
};
// The records of a history folder (<id>.json; <id>.calibration.json files are calibrations, not
// records); a folder that does not exist holds none.
RecordListing listCalibrationRecords(const std::filesystem::path& history);

// <history>/<id>.json; throws std::runtime_error naming the folder when there is no such record.
CalibrationRecord findCalibrationRecord(const std::filesystem::path& history, const std::string& id);

// One line of a comparison: a value or field in either record, and how it changed.
struct RecordDifference {
  std::string name, unit;
  std::optional<double> before, after;  // numbers; absent when the record lacks it
  std::string before_text, after_text;  // for fields that are text (cell, sensors, verdict)
};
// What differs between two records: text fields that differ, then every parameter, residual and
// check of either record (unchanged ones too, with their difference 0), in the first record's order.
std::vector<RecordDifference> diffCalibrationRecords(const CalibrationRecord& before, const CalibrationRecord& after);

}  // namespace stampscan::registration
