#include "schema.hpp"

namespace stampscan::results::schema {

const std::vector<Migration>& migrations() {
  // Append new versions here (and raise kSchemaVersion); never edit a migration that has shipped.
  static const std::vector<Migration> kMigrations = {
      {1,
       "runs",
       {"CREATE TABLE runs ("
        " run_id TEXT PRIMARY KEY,"
        " part_id TEXT NOT NULL,"
        " program TEXT NOT NULL DEFAULT '',"
        " plan TEXT NOT NULL DEFAULT '',"
        " cell TEXT NOT NULL DEFAULT '',"
        " started_utc TEXT NOT NULL,"
        " material TEXT NOT NULL DEFAULT '',"
        " verdict TEXT NOT NULL DEFAULT '',"
        " max_thinning_percent DOUBLE PRECISION,"
        " min_margin_percent DOUBLE PRECISION,"
        " marginal_band_percent DOUBLE PRECISION,"
        " elements BIGINT,"
        " position_rms_mm DOUBLE PRECISION,"
        " strain_rms DOUBLE PRECISION,"
        " data_loss TEXT NOT NULL DEFAULT '',"
        " run_dir TEXT NOT NULL DEFAULT '',"
        " status TEXT NOT NULL CHECK (status IN ('ok', 'failed', 'aborted')),"
        " reason TEXT NOT NULL DEFAULT '',"
        " recorded_utc TEXT NOT NULL)",
        // The history's and the trend's queries: by program or part over time, or by time alone, in
        // the order they return rows (run_id breaks ties), so that no query sorts.
        "CREATE INDEX runs_program_started ON runs (program, started_utc, run_id)",
        "CREATE INDEX runs_part_started ON runs (part_id, started_utc, run_id)",
        "CREATE INDEX runs_started ON runs (started_utc, run_id)"}},
      {2,
       "calibrations",
       {"CREATE TABLE calibrations ("
        " record_id TEXT PRIMARY KEY,"
        " kind TEXT NOT NULL,"
        " created_utc TEXT NOT NULL,"
        " cell TEXT NOT NULL DEFAULT '',"
        " verdict TEXT NOT NULL CHECK (verdict IN ('passed', 'failed', 'accepted')),"
        " accepted_by TEXT NOT NULL DEFAULT '',"
        " summary TEXT NOT NULL DEFAULT '',"
        " record_file TEXT NOT NULL DEFAULT '',"
        " record_json TEXT NOT NULL,"
        " recorded_utc TEXT NOT NULL)",
        "CREATE INDEX calibrations_kind_created ON calibrations (kind, created_utc, record_id)"}},
  };
  return kMigrations;
}

std::vector<std::string> migrationStatements(int found) {
  std::vector<std::string> out;
  for (const Migration& m : migrations())
    if (m.version > found)
      for (const char* statement : m.statements) out.emplace_back(statement);
  out.emplace_back("DELETE FROM schema_version");
  out.push_back("INSERT INTO schema_version (version) VALUES (" + std::to_string(kSchemaVersion) + ")");
  return out;
}

std::string upsertSql(const std::function<std::string(std::size_t)>& placeholder) {
  std::string names, values, updates;
  for (std::size_t i = 0; i < kRunColumnCount; ++i) {
    const std::string name = kRunColumns[i];
    // Appended piece by piece: GCC 12 warns wrongly (-Wrestrict) on "literal" + std::string.
    if (i > 0) names += ", ", values += ", ";
    names += name;
    values += placeholder(i);
    if (i > 1) updates += ", ";
    if (i > 0) updates.append(name).append(" = excluded.").append(name);
  }
  const std::string recorded = placeholder(kRunColumnCount);
  return "INSERT INTO runs (" + names + ", recorded_utc) VALUES (" + values + ", " + recorded +
         ") ON CONFLICT (run_id) DO UPDATE SET " + updates + ", recorded_utc = excluded.recorded_utc";
}

std::string selectSql(const RunFilter& filter, const std::function<std::string(std::size_t)>& placeholder,
                      std::vector<std::string>& values) {
  std::string columns;
  for (std::size_t i = 0; i < kRunColumnCount; ++i) columns += std::string(i ? ", " : "") + kRunColumns[i];
  std::string where;
  const auto condition = [&](const char* sql_before_value, const std::string& value) {
    where += (where.empty() ? " WHERE " : " AND ") + std::string(sql_before_value) + placeholder(values.size());
    values.push_back(value);
  };
  if (!filter.part_id.empty()) condition("part_id = ", filter.part_id);
  if (!filter.program.empty()) condition("program = ", filter.program);
  if (!filter.verdict.empty()) condition("verdict = ", filter.verdict);
  if (!filter.since.empty()) condition("started_utc >= ", filter.since);
  if (filter.status) condition("status = ", toString(*filter.status));
  if (filter.limit == 0) return "SELECT " + columns + " FROM runs" + where + " ORDER BY started_utc, run_id";
  // The newest `limit` runs, returned oldest first like every other query.
  return "SELECT " + columns + " FROM (SELECT " + columns + " FROM runs" + where +
         " ORDER BY started_utc DESC, run_id DESC LIMIT " + std::to_string(filter.limit) +
         ") AS newest ORDER BY started_utc, run_id";
}

std::string calibrationUpsertSql(const std::function<std::string(std::size_t)>& placeholder) {
  std::string names, values, updates;
  for (std::size_t i = 0; i < kCalibrationColumnCount; ++i) {
    const std::string name = kCalibrationColumns[i];
    if (i > 0) names += ", ", values += ", ";
    names += name;
    values += placeholder(i);
    if (i > 1) updates += ", ";
    if (i > 0) updates.append(name).append(" = excluded.").append(name);
  }
  return "INSERT INTO calibrations (" + names + ", recorded_utc) VALUES (" + values + ", " +
         placeholder(kCalibrationColumnCount) + ") ON CONFLICT (record_id) DO UPDATE SET " + updates +
         ", recorded_utc = excluded.recorded_utc";
}

std::string calibrationSelectSql(const std::string& kind, std::size_t limit,
                                 const std::function<std::string(std::size_t)>& placeholder,
                                 std::vector<std::string>& values) {
  std::string columns;
  for (std::size_t i = 0; i < kCalibrationColumnCount; ++i)
    columns += std::string(i ? ", " : "") + kCalibrationColumns[i];
  std::string where;
  if (!kind.empty()) {
    where = " WHERE kind = " + placeholder(values.size());
    values.push_back(kind);
  }
  if (limit == 0) return "SELECT " + columns + " FROM calibrations" + where + " ORDER BY created_utc, record_id";
  return "SELECT " + columns + " FROM (SELECT " + columns + " FROM calibrations" + where +
         " ORDER BY created_utc DESC, record_id DESC LIMIT " + std::to_string(limit) +
         ") AS newest ORDER BY created_utc, record_id";
}

std::vector<std::string> calibrationValues(const CalibrationRow& r) {
  return {r.record_id, r.kind, r.created_utc, r.cell, r.verdict, r.accepted_by, r.summary, r.record_file, r.record_json};
}

std::string newerSchemaMessage(const std::string& location, int found) {
  return location + ": results database of schema version " + std::to_string(found) + ", newer than this program's " +
         std::to_string(kSchemaVersion) + "; refusing to read or write it (update the station software)";
}

}  // namespace stampscan::results::schema

#include <ctime>

namespace stampscan::results::schema {
std::string nowUtc() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}
}  // namespace stampscan::results::schema
