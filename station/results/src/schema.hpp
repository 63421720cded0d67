// The results schema, written once for both databases: the migrations and the run columns. The SQL
// is the common subset of SQLite and PostgreSQL (TEXT, BIGINT, DOUBLE PRECISION, ON CONFLICT).
#pragma once

#include "stampscan/results/results_store.hpp"

#include <functional>
#include <string>
#include <vector>

namespace stampscan::results::schema {

// Migration k brings a database from version k-1 to k; version 0 is an empty database.
struct Migration {
  int version;
  const char* description;
  std::vector<const char*> statements;
};
const std::vector<Migration>& migrations();
// The statements that bring a database of version `found` to kSchemaVersion, the version row
// included; to run in one transaction after kCreateVersionTable.
std::vector<std::string> migrationStatements(int found);

// The table that holds the version: one row. Created before any migration runs.
inline constexpr const char* kCreateVersionTable = "CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)";

// The run columns in the order selectRuns reads them and upsertRun binds them.
inline constexpr const char* kRunColumns[] = {
    "run_id",           "part_id",          "program",
    "plan",             "cell",             "started_utc",
    "material",         "verdict",          "max_thinning_percent",
    "min_margin_percent", "marginal_band_percent", "elements",
    "position_rms_mm",  "strain_rms",       "data_loss",
    "run_dir",          "status",           "reason"};
inline constexpr std::size_t kRunColumnCount = sizeof kRunColumns / sizeof kRunColumns[0];

// A run row's fields in kRunColumns order, the one mapping both databases read and write by:
// `columns` has text(s), number(optional double) and count(optional integer), called once per
// column with the field (const when writing). `status` stands for the status column, as its text.
template <class Row, class Status, class Columns>
void visitRunColumns(Row& run, Status& status, Columns& columns) {
  columns.text(run.run_id), columns.text(run.part_id), columns.text(run.program), columns.text(run.plan);
  columns.text(run.cell), columns.text(run.started_utc), columns.text(run.material), columns.text(run.verdict);
  columns.number(run.max_thinning_percent), columns.number(run.min_margin_percent);
  columns.number(run.marginal_band_percent), columns.count(run.elements);
  columns.number(run.position_rms_mm), columns.number(run.strain_rms), columns.text(run.data_loss);
  columns.text(run.run_dir), columns.text(status), columns.text(run.reason);
}

// "INSERT INTO runs (...) VALUES (...) ON CONFLICT (run_id) DO UPDATE SET ...", with the
// placeholders the database wants (? or $1, ...): placeholder(i) for column i (from 0).
std::string upsertSql(const std::function<std::string(std::size_t)>& placeholder);

// "SELECT ... FROM runs WHERE ... ORDER BY ...": the filter's conditions with placeholders for its
// values, which are appended to `values` in placeholder order.
std::string selectSql(const RunFilter& filter, const std::function<std::string(std::size_t)>& placeholder,
                      std::vector<std::string>& values);

// The calibration columns (all text) in the order the statements below bind and read them.
inline constexpr const char* kCalibrationColumns[] = {"record_id", "kind",    "created_utc", "cell",       "verdict",
                                                      "accepted_by", "summary", "record_file", "record_json"};
inline constexpr std::size_t kCalibrationColumnCount = sizeof kCalibrationColumns / sizeof kCalibrationColumns[0];
// The upsert of one calibration row, placeholder(i) for column i and placeholder(count) for the
// time it was recorded.
std::string calibrationUpsertSql(const std::function<std::string(std::size_t)>& placeholder);
// The calibrations of a kind ("" for all), oldest first; with `limit`, the newest `limit`. The kind's
// value, when there is one, is appended to `values`.
std::string calibrationSelectSql(const std::string& kind, std::size_t limit,
                                 const std::function<std::string(std::size_t)>& placeholder,
                                 std::vector<std::string>& values);
// The row's values in kCalibrationColumns order.
std::vector<std::string> calibrationValues(const CalibrationRow& row);

// The error message for a database newer than this program.
std::string newerSchemaMessage(const std::string& location, int found);

}  // namespace stampscan::results::schema

namespace stampscan::results::schema {
// Now, as the ISO UTC text the rows hold (second resolution).
std::string nowUtc();
}  // namespace stampscan::results::schema
