// The results history in an SQLite file (RUNS/results.sqlite), through SQLiteCpp. The default
// rollback journal, not WAL: WAL needs a writable -shm file beside the database even to read it,
// and the history must read a database that an operator may only read.
#include "schema.hpp"
#include "stampscan/results/results_store.hpp"

#include <SQLiteCpp/SQLiteCpp.h>
#include <sqlite3.h>

namespace stampscan::results {

namespace {

namespace fs = std::filesystem;

// One write transaction: BEGIN IMMEDIATE takes the write lock at once (waiting at most the busy
// timeout), so two writers never both read the schema and then both migrate it. Rolled back unless
// committed.
class WriteTransaction {
 public:
  explicit WriteTransaction(SQLite::Database& db) : db_(db) { db_.exec("BEGIN IMMEDIATE"); }
  ~WriteTransaction() {
    if (!committed_) {
      try {
        db_.exec("ROLLBACK");
      } catch (const SQLite::Exception&) {
        // SQLite may already have rolled back (after SQLITE_FULL, for example); nothing is left to undo.
      }
    }
  }
  WriteTransaction(const WriteTransaction&) = delete;
  WriteTransaction& operator=(const WriteTransaction&) = delete;
  void commit() {
    db_.exec("COMMIT");
    committed_ = true;
  }

 private:
  SQLite::Database& db_;
  bool committed_ = false;
};

class SqliteStore final : public ResultsStore {
 public:
  SqliteStore(const fs::path& file, const StoreOptions& options) : ResultsStore(file.string()), options_(options) {
    std::error_code error;
    if (options.read_only && !fs::exists(file, error))
      throw ResultsError(location() + ": no results database (no run has been recorded in this runs folder yet)");
    try {
      const int flags = options.read_only ? SQLite::OPEN_READONLY : SQLite::OPEN_READWRITE | SQLite::OPEN_CREATE;
      db_ = std::make_unique<SQLite::Database>(file.string(), flags, static_cast<int>(options.lock_timeout.count()));
    } catch (const SQLite::Exception& e) {
      fail("cannot be opened", e);
    }
    // SQLite opens a file it may not write read-only without a word; say so now rather than at the
    // first write.
    if (!options.read_only && sqlite3_db_readonly(db_->getHandle(), "main") == 1)
      throw ResultsError(location() + ": read-only (the file cannot be written); runs cannot be recorded in it");
    try {
      const int version = readVersion();
      if (version > kSchemaVersion) throw ResultsError(schema::newerSchemaMessage(location(), version));
      if (version < kSchemaVersion) {
        if (options.read_only)
          throw ResultsError(location() + ": results database of schema version " + std::to_string(version) +
                             ", older than this program's " + std::to_string(kSchemaVersion) +
                             "; record a run in it to migrate it first");
        migrate();
      }
    } catch (const SQLite::Exception& e) {
      fail("cannot be read", e);
    }
  }

 protected:
  void upsertRuns(const std::vector<RunRow>& runs) override {
    const RunRow* current = &runs.front();
    try {
      WriteTransaction transaction(*db_);
      SQLite::Statement insert(*db_, schema::upsertSql([](std::size_t) { return std::string("?"); }));
      const std::string recorded = schema::nowUtc();
      for (const RunRow& run : runs) {
        current = &run;
        bind(insert, run, recorded);
        insert.exec();
        insert.reset();
      }
      transaction.commit();
    } catch (const SQLite::Exception& e) {
      fail(runs.size() == 1 ? "run " + current->run_id + " not recorded"
                            : std::to_string(runs.size()) + " runs not recorded (at run " + current->run_id + ")",
           e);
    }
  }

  static void bind(SQLite::Statement& insert, const RunRow& run, const std::string& recorded) {
    struct Binder {
      SQLite::Statement& insert;
      int k = 1;
      void text(const std::string& v) { insert.bind(k++, v); }
      void number(const std::optional<double>& v) {
        if (v) insert.bind(k++, *v);
        else insert.bind(k++);
      }
      void count(const std::optional<std::int64_t>& v) {
        if (v) insert.bind(k++, *v);
        else insert.bind(k++);
      }
    } binder{insert};
    const std::string status = toString(run.status);
    schema::visitRunColumns(run, status, binder);
    binder.text(recorded);
  }

  std::vector<RunRow> selectRuns(const RunFilter& filter) const override {
    std::vector<RunRow> runs;
    try {
      std::vector<std::string> values;
      SQLite::Statement query(*db_, schema::selectSql(filter, [](std::size_t) { return std::string("?"); }, values));
      for (std::size_t i = 0; i < values.size(); ++i) query.bind(static_cast<int>(i + 1), values[i]);
      while (query.executeStep()) {
        RunRow& r = runs.emplace_back();
        struct Reader {
          SQLite::Statement& query;
          int c = 0;
          void text(std::string& out) { out = query.getColumn(c++).getString(); }
          void number(std::optional<double>& out) {
            const SQLite::Column column = query.getColumn(c++);
            if (!column.isNull()) out = column.getDouble();
          }
          void count(std::optional<std::int64_t>& out) {
            const SQLite::Column column = query.getColumn(c++);
            if (!column.isNull()) out = column.getInt64();
          }
        } reader{query};
        std::string status;
        schema::visitRunColumns(r, status, reader);
        try {
          r.status = runStatusFromString(status);
        } catch (const ResultsError& e) {
          throw ResultsError(location() + ": run " + r.run_id + ": " + e.what());
        }
      }
    } catch (const SQLite::Exception& e) {
      fail("cannot be queried", e);
    }
    return runs;
  }

  int storedSchemaVersion() const override {
    try {
      return readVersion();
    } catch (const SQLite::Exception& e) {
      fail("cannot be read", e);
    }
  }

  void upsertCalibration(const CalibrationRow& row) override {
    try {
      WriteTransaction transaction(*db_);
      SQLite::Statement insert(*db_, schema::calibrationUpsertSql([](std::size_t) { return std::string("?"); }));
      int k = 1;
      for (const std::string& value : schema::calibrationValues(row)) insert.bind(k++, value);
      insert.bind(k, schema::nowUtc());
      insert.exec();
      transaction.commit();
    } catch (const SQLite::Exception& e) {
      fail("calibration " + row.record_id + " not recorded", e);
    }
  }

  std::vector<CalibrationRow> selectCalibrations(const std::string& kind, std::size_t limit) const override {
    std::vector<CalibrationRow> rows;
    try {
      std::vector<std::string> values;
      SQLite::Statement query(*db_, schema::calibrationSelectSql(kind, limit, [](std::size_t) { return std::string("?"); }, values));
      for (std::size_t i = 0; i < values.size(); ++i) query.bind(static_cast<int>(i + 1), values[i]);
      while (query.executeStep()) {
        CalibrationRow& r = rows.emplace_back();
        int c = 0;
        for (std::string* field : {&r.record_id, &r.kind, &r.created_utc, &r.cell, &r.verdict, &r.accepted_by, &r.summary,
                                   &r.record_file, &r.record_json})
          *field = query.getColumn(c++).getString();
      }
    } catch (const SQLite::Exception& e) {
      fail("cannot be queried", e);
    }
    return rows;
  }

 private:
  // 0 for an empty database (no schema_version table, or no row in it).
  int readVersion() const {
    SQLite::Statement table(*db_, "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'schema_version'");
    if (!table.executeStep() || table.getColumn(0).getInt() == 0) return 0;
    SQLite::Statement version(*db_, "SELECT max(version) FROM schema_version");
    if (!version.executeStep() || version.getColumn(0).isNull()) return 0;
    return version.getColumn(0).getInt();
  }

  void migrate() {
    WriteTransaction transaction(*db_);
    db_->exec(schema::kCreateVersionTable);
    // Read again under the write lock: another process may have migrated meanwhile.
    const int found = readVersion();
    if (found > kSchemaVersion) throw ResultsError(schema::newerSchemaMessage(location(), found));
    for (const std::string& statement : schema::migrationStatements(found)) db_->exec(statement);
    transaction.commit();
  }

  [[noreturn]] void fail(const std::string& what, const SQLite::Exception& e) const {
    std::string why;
    switch (e.getErrorCode()) {
      case SQLITE_BUSY:
      case SQLITE_LOCKED:
        why = "locked by another connection's write transaction (waited " +
              std::to_string(options_.lock_timeout.count()) + " ms)";
        break;
      case SQLITE_READONLY: why = std::string("read-only (") + e.what() + ")"; break;
      case SQLITE_FULL: why = "the disk is full"; break;
      case SQLITE_NOTADB: why = "not an SQLite database"; break;
      case SQLITE_CORRUPT: why = std::string("damaged (") + e.what() + ")"; break;
      case SQLITE_CANTOPEN:
        why = std::string(e.what()) + " (does the folder exist, and may this user write in it?)";
        break;
      default: why = e.what();
    }
    throw ResultsError(location() + ": " + what + ": " + why);
  }

  StoreOptions options_;
  std::unique_ptr<SQLite::Database> db_;
};

}  // namespace

std::unique_ptr<ResultsStore> openSqliteStore(const std::filesystem::path& file, const StoreOptions& options) {
  return std::make_unique<SqliteStore>(file, options);
}

}  // namespace stampscan::results
