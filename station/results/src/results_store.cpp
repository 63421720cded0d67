// What every results database shares: the checks on a record before it is written, the filter's
// normalising, and choosing the database from a runs folder or a URL.
#include "stampscan/results/results_store.hpp"

#include <regex>

namespace stampscan::results {

ResultsStore::~ResultsStore() = default;

const char* toString(RunStatus status) {
  switch (status) {
    case RunStatus::Ok: return "ok";
    case RunStatus::Failed: return "failed";
    case RunStatus::Aborted: return "aborted";
  }
  return "?";
}

RunStatus runStatusFromString(const std::string& text) {
  if (text == "ok") return RunStatus::Ok;
  if (text == "failed") return RunStatus::Failed;
  if (text == "aborted") return RunStatus::Aborted;
  throw ResultsError("unknown run status \"" + text + "\" (expected ok, failed or aborted)");
}

void ResultsStore::recordRun(const RunRow& run) {
  check(run);
  upsertRuns({run});
}

void ResultsStore::recordRuns(const std::vector<RunRow>& runs) {
  for (const RunRow& run : runs) check(run);
  if (!runs.empty()) upsertRuns(runs);
}

void ResultsStore::check(const RunRow& run) const {
  if (run.run_id.empty()) throw ResultsError(location_ + ": a run without a run id cannot be recorded");
  if (run.started_utc.empty())
    throw ResultsError(location_ + ": run " + run.run_id + " has no start time and cannot be recorded");
  if (run.status != RunStatus::Ok && run.reason.empty())
    throw ResultsError(location_ + ": run " + run.run_id + " is " + toString(run.status) + " but gives no reason");
}

void ResultsStore::recordFailedRun(RunRow run, const std::string& reason) {
  if (reason.empty()) throw ResultsError(location_ + ": run " + run.run_id + " recorded as failed needs a reason");
  run.status = RunStatus::Failed;
  run.reason = reason;
  recordRun(run);
}

std::vector<RunRow> ResultsStore::queryRuns(const RunFilter& filter) const {
  RunFilter normalized = filter;
  if (!filter.since.empty()) normalized.since = normalizeSince(filter.since);
  return selectRuns(normalized);
}

int ResultsStore::schemaVersion() const { return storedSchemaVersion(); }

void ResultsStore::recordCalibration(const CalibrationRow& c) {
  if (c.record_id.empty() || c.kind.empty() || c.created_utc.empty())
    throw ResultsError(location_ + ": a calibration record needs an id, a kind and a creation time");
  if (c.verdict != "passed" && c.verdict != "failed" && c.verdict != "accepted")
    throw ResultsError(location_ + ": calibration " + c.record_id + " has the verdict \"" + c.verdict +
                       "\" (expected passed, failed or accepted)");
  upsertCalibration(c);
}

std::vector<CalibrationRow> ResultsStore::queryCalibrations(const std::string& kind, std::size_t limit) const {
  return selectCalibrations(kind, limit);
}

bool isDatabaseUrl(const std::string& runs_dir_or_url) {
  return runs_dir_or_url.starts_with("postgresql://") || runs_dir_or_url.starts_with("postgres://");
}

std::unique_ptr<ResultsStore> openResultsStore(const std::string& runs_dir_or_url, const StoreOptions& options) {
  if (runs_dir_or_url.empty()) throw ResultsError("results: no runs folder or database URL given");
  if (isDatabaseUrl(runs_dir_or_url)) return openPostgresStore(runs_dir_or_url, options);
  const std::filesystem::path runs = runs_dir_or_url;
  std::error_code error;
  if (!std::filesystem::is_directory(runs, error))
    throw ResultsError(runs.string() + ": not a runs folder (no such folder)");
  return openSqliteStore(runs / kSqliteFileName, options);
}

std::string normalizeSince(const std::string& text) {
  // Rows hold "YYYY-MM-DDTHH:MM:SSZ", so a prefix of that form compares as a time.
  static const std::regex pattern(R"((\d{4})-(\d{2})-(\d{2})(?:[T ](\d{2}):(\d{2})(?::(\d{2}))?Z?)?)");
  std::smatch m;
  if (!std::regex_match(text, m, pattern))
    throw ResultsError("--since \"" + text + "\": expected a date 2026-11-01 or a UTC time 2026-11-01T06:00[:00]");
  const int month = std::stoi(m[2].str()), day = std::stoi(m[3].str());
  if (month < 1 || month > 12 || day < 1 || day > 31)
    throw ResultsError("--since \"" + text + "\": no such date");
  std::string out = m[1].str() + "-" + m[2].str() + "-" + m[3].str();
  if (m[4].matched) {
    if (std::stoi(m[4].str()) > 23 || std::stoi(m[5].str()) > 59 || (m[6].matched && std::stoi(m[6].str()) > 59))
      throw ResultsError("--since \"" + text + "\": no such time of day");
    out.append("T").append(m[4].str()).append(":").append(m[5].str()).append(":");
    out.append(m[6].matched ? m[6].str() : std::string("00")).append("Z");
  }
  return out;
}

}  // namespace stampscan::results
