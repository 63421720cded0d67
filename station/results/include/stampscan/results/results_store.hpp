// The results history: one row per run, and one per calibration or verification of the cell, in one database. By default SQLite in the runs folder
// (RUNS/results.sqlite); PostgreSQL when given a URL (postgresql://...), for a plant whose cells
// write to one place. Both implement ResultsStore with the same versioned schema:
//   - opening a database migrates it to this program's schema version, in one transaction;
//     a database of a newer version is refused (ResultsError), never written;
//   - every write is one transaction; recording a run whose id is already there updates it
//     (a report run again replaces the row, it never adds a second one);
//   - a locked database is waited for at most StoreOptions::lock_timeout, then ResultsError.
// Thread safety: a store is one connection; use it from one thread at a time. Several processes
// (several stores) may write to one database: the database serialises them.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::results {

// The schema version this program writes (see src/schema.cpp for the migrations).
inline constexpr int kSchemaVersion = 2;
// The file name of the SQLite database inside a runs folder.
inline constexpr const char* kSqliteFileName = "results.sqlite";

// A database that cannot be opened, migrated, read or written: the message names the database
// (file, or URL without its password) and what is wrong.
class ResultsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class RunStatus { Ok, Failed, Aborted };
const char* toString(RunStatus status);  // "ok", "failed", "aborted"
// Throws ResultsError for any other text.
RunStatus runStatusFromString(const std::string& text);

// One run as a row of the history (its folder's run.json and report.json, run_recording.hpp). Text fields are "" when unknown; numbers are empty when the run has none (a failed run
// has no verdict and no figures).
struct RunRow {
  std::string run_id;       // the run folder's name, unique
  std::string part_id, program, plan, cell;
  std::string started_utc;  // ISO 8601, UTC: 2026-11-24T09:16:02Z
  std::string material;
  std::string verdict;      // good / marginal / failed, as the report gives it
  std::optional<double> max_thinning_percent;
  std::optional<double> min_margin_percent;     // the smallest safety margin (engineering strain %)
  std::optional<double> marginal_band_percent;  // the material's safety margin: below it is marginal
  std::optional<std::int64_t> elements;
  std::optional<double> position_rms_mm, strain_rms;  // accuracy against the simulated part, when known
  std::string data_loss;    // "" when nothing was lost
  std::string run_dir;      // the run folder, as it was recorded
  RunStatus status = RunStatus::Ok;
  std::string reason;       // why the run failed or was aborted
};

// Which runs a query returns; empty fields do not filter. Runs come oldest first.
struct RunFilter {
  std::string part_id, program, verdict;
  std::string since;  // a date (2026-11-01) or a UTC time (2026-11-01T06:00[:00][Z]); checked
  std::optional<RunStatus> status;
  std::size_t limit = 0;  // 0: all; otherwise the newest `limit` runs (still oldest first)
};

// One calibration or verification of the cell (registration/calibration_record.hpp, which the
// station turns into a row): the fields a listing needs, and the whole record as its file holds it.
struct CalibrationRow {
  std::string record_id;    // unique
  std::string kind;         // "digitizer", "cameras", "verification"
  std::string created_utc;  // ISO 8601, UTC
  std::string cell, verdict, accepted_by;  // verdict: passed, failed or accepted
  std::string summary;      // one line: the checks and their outcome
  std::string record_file;  // where the record's file (and its traces) are kept
  std::string record_json;  // the record as its file holds it
  bool operator==(const CalibrationRow&) const = default;
};

struct StoreOptions {
  // History and trend only read: the database is opened read-only and must exist already.
  bool read_only = false;
  // How long a write waits for another connection's write transaction before giving up.
  std::chrono::milliseconds lock_timeout{5000};
};

class ResultsStore {
 public:
  virtual ~ResultsStore();
  ResultsStore(const ResultsStore&) = delete;
  ResultsStore& operator=(const ResultsStore&) = delete;

  // Inserts the run, or replaces the row with the same run_id. Throws ResultsError when the record
  // lacks an id or start time, or the database cannot be written.
  void recordRun(const RunRow& run);
  // Many runs in one transaction (all or none): re-indexing a runs folder, importing a history.
  void recordRuns(const std::vector<RunRow>& runs);
  // The run as failed, with its reason (which must not be empty); verdict and figures as given.
  void recordFailedRun(RunRow run, const std::string& reason);
  std::vector<RunRow> queryRuns(const RunFilter& filter = {}) const;
  // Inserts the calibration, or replaces the row with the same record id. Throws ResultsError when
  // the row lacks an id, kind or creation time, has another verdict than passed, failed or
  // accepted, or the database cannot be written.
  void recordCalibration(const CalibrationRow& calibration);
  // Oldest first; `kind` "" for every kind; `limit` 0 for all, else the newest `limit`.
  std::vector<CalibrationRow> queryCalibrations(const std::string& kind = "", std::size_t limit = 0) const;
  int schemaVersion() const;
  // The database, for messages: the file, or the URL without its password.
  const std::string& location() const { return location_; }

 protected:
  explicit ResultsStore(std::string location) : location_(std::move(location)) {}
  // The implementations only talk to their database; checks and normalising happen above.
  // Inserts or replaces the rows in one transaction.
  virtual void upsertRuns(const std::vector<RunRow>& runs) = 0;
  virtual std::vector<RunRow> selectRuns(const RunFilter& normalized) const = 0;
  virtual int storedSchemaVersion() const = 0;
  virtual void upsertCalibration(const CalibrationRow& calibration) = 0;
  virtual std::vector<CalibrationRow> selectCalibrations(const std::string& kind, std::size_t limit) const = 0;

 private:
  void check(const RunRow& run) const;

  std::string location_;
};

// True for postgresql:// and postgres:// URLs.
bool isDatabaseUrl(const std::string& runs_dir_or_url);
// A runs folder as it is, a URL with its password replaced by ***: what messages may show.
std::string locationForMessages(const std::string& runs_dir_or_url);
// A runs folder (its results.sqlite, created when writing) or a PostgreSQL URL.
std::unique_ptr<ResultsStore> openResultsStore(const std::string& runs_dir_or_url, const StoreOptions& options = {});
std::unique_ptr<ResultsStore> openSqliteStore(const std::filesystem::path& file, const StoreOptions& options = {});
std::unique_ptr<ResultsStore> openPostgresStore(const std::string& url, const StoreOptions& options = {});

// "2026-11-01" or "2026-11-01T06:00[:00][Z]" (a space for the T is accepted) as the ISO UTC text
// the rows hold; throws ResultsError naming the text when it is not such a date.
std::string normalizeSince(const std::string& text);

}  // namespace stampscan::results
