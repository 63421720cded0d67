// The same store tests against SQLite and against a real PostgreSQL server: migrations from an
// empty database, a newer schema refused, insert and update, failed runs with their reason, the
// history's filters, a locked database (a clear error within the lock timeout, never a hang).
#include "results_test_support.hpp"

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>
#include <pqxx/pqxx>

#include <chrono>

namespace stampscan::results {
namespace {

using test::makeRun;

// One database kind under test.
class Backend {
 public:
  virtual ~Backend() = default;
  // A runs folder or URL of an empty database; empty (with the reason) when unavailable.
  virtual std::string fresh(std::string& skip_reason) = 0;
  virtual void setStoredVersion(const std::string& where, int version) = 0;
  // Runs one statement on the database, outside any store.
  virtual void execute(const std::string& where, const std::string& sql) = 0;
  // Another connection that holds a write transaction on the runs table until destroyed.
  virtual std::shared_ptr<void> holdWriteLock(const std::string& where) = 0;
};

class SqliteBackend final : public Backend {
 public:
  std::string fresh(std::string&) override { return dir_.path().string(); }
  void setStoredVersion(const std::string& where, int version) override {
    execute(where, "UPDATE schema_version SET version = " + std::to_string(version));
  }
  void execute(const std::string& where, const std::string& sql) override {
    SQLite::Database db(where + "/" + kSqliteFileName, SQLite::OPEN_READWRITE);
    db.exec(sql);
  }
  std::shared_ptr<void> holdWriteLock(const std::string& where) override {
    auto db = std::make_shared<SQLite::Database>(where + "/" + kSqliteFileName, SQLite::OPEN_READWRITE);
    db->exec("BEGIN IMMEDIATE");
    db->exec("DELETE FROM runs WHERE run_id = 'none'");
    return db;
  }

 private:
  test::TempDir dir_;
};

class PostgresBackend final : public Backend {
 public:
  std::string fresh(std::string& skip_reason) override {
    test::PostgresServer* server = test::PostgresServer::get(skip_reason);
    return server ? server->freshDatabase() : std::string();
  }
  void setStoredVersion(const std::string& where, int version) override {
    execute(where, "UPDATE schema_version SET version = " + std::to_string(version));
  }
  void execute(const std::string& where, const std::string& sql) override {
    pqxx::connection c(where);
    pqxx::work w(c);
    w.exec(sql);
    w.commit();
  }
  std::shared_ptr<void> holdWriteLock(const std::string& where) override {
    struct Held {
      pqxx::connection connection;
      pqxx::work work;
      explicit Held(const std::string& url) : connection(url), work(connection) {
        work.exec("LOCK TABLE runs IN ACCESS EXCLUSIVE MODE");
      }
    };
    return std::make_shared<Held>(where);
  }
};

class StoreContract : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "sqlite") backend_ = std::make_unique<SqliteBackend>();
    else backend_ = std::make_unique<PostgresBackend>();
    std::string reason;
    where_ = backend_->fresh(reason);
    if (where_.empty()) GTEST_SKIP() << "PostgreSQL server could not start: " << reason;
  }
  std::unique_ptr<ResultsStore> open(StoreOptions options = {}) { return openResultsStore(where_, options); }

  std::unique_ptr<Backend> backend_;
  std::string where_;
};

TEST_P(StoreContract, MigratesAnEmptyDatabaseToTheCurrentSchema) {
  {
    const auto store = open();
    EXPECT_EQ(store->schemaVersion(), kSchemaVersion);
    EXPECT_TRUE(store->queryRuns().empty());
    store->recordRun(makeRun("P1", "door-outer", 1, 8));
  }
  // Opening again migrates nothing and loses nothing; a read-only store reads it.
  StoreOptions read_only;
  read_only.read_only = true;
  const auto again = open(read_only);
  EXPECT_EQ(again->schemaVersion(), kSchemaVersion);
  ASSERT_EQ(again->queryRuns().size(), 1u);
}

TEST_P(StoreContract, RefusesADatabaseOfANewerSchema) {
  open()->recordRun(makeRun("P1", "door-outer", 1, 8));
  backend_->setStoredVersion(where_, kSchemaVersion + 1);
  for (bool read_only : {false, true}) {
    StoreOptions options;
    options.read_only = read_only;
    try {
      open(options);
      FAIL() << "a newer schema was accepted";
    } catch (const ResultsError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("newer than this program"), std::string::npos) << message;
      EXPECT_NE(message.find("version " + std::to_string(kSchemaVersion + 1)), std::string::npos) << message;
    }
  }
}

// A database of version 1 (runs only, before calibrations were rows) is migrated on opening: its
// runs are kept and calibrations can be recorded.
TEST_P(StoreContract, MigratesAVersionOneDatabaseKeepingItsRuns) {
  open()->recordRun(makeRun("P1", "door-outer", 1, 8));
  backend_->execute(where_, "DROP TABLE calibrations");
  backend_->setStoredVersion(where_, 1);
  const auto store = open();
  EXPECT_EQ(store->schemaVersion(), kSchemaVersion);
  ASSERT_EQ(store->queryRuns().size(), 1u);
  EXPECT_TRUE(store->queryCalibrations().empty());
  CalibrationRow row{"20261124-080000-digitizer", "digitizer", "2026-11-24T08:00:00Z", "virtual cell", "passed", "",
                     "1 of 1 checks passed", "cal/history/20261124-080000-digitizer.json", "{}"};
  store->recordCalibration(row);
  EXPECT_EQ(store->queryCalibrations().size(), 1u);
}

TEST_P(StoreContract, RecordsCalibrationsReplacesThemByIdAndListsThemByKind) {
  const auto store = open();
  CalibrationRow digitizer{"20261124-080000-digitizer", "digitizer", "2026-11-24T08:00:00Z", "virtual cell", "failed",
                           "", "0 of 1 checks passed; failed: sphere residual RMS", "h/20261124-080000-digitizer.json",
                           "{\"id\": \"it's \\\"quoted\\\"\"}"};
  CalibrationRow cameras{"20261124-080001-cameras", "cameras", "2026-11-24T08:00:01Z", "virtual cell", "accepted",
                         "J. O'Neill", "3 of 4 checks passed", "h/20261124-080001-cameras.json", "{}"};
  CalibrationRow verification{"20261125-070000-verification", "verification", "2026-11-25T07:00:00Z", "virtual cell",
                              "passed", "", "2 of 2 checks passed", "h/20261125-070000-verification.json", "{}"};
  store->recordCalibration(verification);
  store->recordCalibration(digitizer);
  store->recordCalibration(cameras);
  digitizer.verdict = "accepted";
  digitizer.accepted_by = "J. Smith";
  store->recordCalibration(digitizer);  // the same record again: its row is replaced
  const auto all = store->queryCalibrations();
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0], digitizer);  // oldest first, every field as written
  EXPECT_EQ(all[1], cameras);
  EXPECT_EQ(all[2], verification);
  const auto verifications = store->queryCalibrations("verification");
  ASSERT_EQ(verifications.size(), 1u);
  EXPECT_EQ(verifications[0].record_id, verification.record_id);
  const auto newest = store->queryCalibrations("", 1);
  ASSERT_EQ(newest.size(), 1u);
  EXPECT_EQ(newest[0].record_id, verification.record_id);

  CalibrationRow bad = verification;
  bad.verdict = "maybe";
  EXPECT_THROW(store->recordCalibration(bad), ResultsError);
  bad = verification;
  bad.record_id.clear();
  EXPECT_THROW(store->recordCalibration(bad), ResultsError);
}

TEST_P(StoreContract, RecordsARunAndUpdatesItWhenRecordedAgain) {
  const auto store = open();
  RunRow run = makeRun("P7", "hood", 3, 9);
  run.position_rms_mm = 0.021;
  run.strain_rms = 0.004;
  run.reason = "";
  run.data_loss = "2 stereo views missing, 'quoted' \"text\"";
  store->recordRun(run);
  run.verdict = "marginal";
  run.min_margin_percent = 4.5;
  store->recordRun(run);  // the report run again: the row is replaced
  const auto runs = store->queryRuns();
  ASSERT_EQ(runs.size(), 1u);
  const RunRow& r = runs[0];
  EXPECT_EQ(r.run_id, run.run_id);
  EXPECT_EQ(r.part_id, "P7");
  EXPECT_EQ(r.program, "hood");
  EXPECT_EQ(r.plan, "pan");
  EXPECT_EQ(r.cell, "virtual");
  EXPECT_EQ(r.started_utc, "2026-11-03T09:00:00Z");
  EXPECT_EQ(r.material, "DC04");
  EXPECT_EQ(r.verdict, "marginal");
  EXPECT_DOUBLE_EQ(*r.min_margin_percent, 4.5);
  EXPECT_DOUBLE_EQ(*r.max_thinning_percent, 12.5);
  EXPECT_DOUBLE_EQ(*r.marginal_band_percent, 10.0);
  EXPECT_EQ(*r.elements, 1200);
  EXPECT_DOUBLE_EQ(*r.position_rms_mm, 0.021);
  EXPECT_DOUBLE_EQ(*r.strain_rms, 0.004);
  EXPECT_EQ(r.data_loss, run.data_loss);
  EXPECT_EQ(r.run_dir, run.run_dir);
  EXPECT_EQ(r.status, RunStatus::Ok);
}

TEST_P(StoreContract, RecordsAFailedRunWithItsReason) {
  const auto store = open();
  RunRow run = makeRun("P2", "hood", 4, 10);
  run.verdict.clear();
  run.max_thinning_percent.reset();
  run.min_margin_percent.reset();
  run.elements.reset();
  store->recordFailedRun(run, "cloud4d.ply: damaged (truncated after 812 of 1200 vertices)");
  EXPECT_THROW(store->recordFailedRun(makeRun("P3", "hood", 4, 11), ""), ResultsError);
  RunRow aborted = makeRun("P4", "hood", 4, 12);
  aborted.status = RunStatus::Aborted;
  EXPECT_THROW(store->recordRun(aborted), ResultsError);  // aborted needs a reason
  aborted.reason = "light curtain interrupted";
  store->recordRun(aborted);

  const auto runs = store->queryRuns();
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].status, RunStatus::Failed);
  EXPECT_EQ(runs[0].reason, "cloud4d.ply: damaged (truncated after 812 of 1200 vertices)");
  EXPECT_FALSE(runs[0].min_margin_percent.has_value());
  EXPECT_FALSE(runs[0].elements.has_value());
  EXPECT_EQ(runs[1].status, RunStatus::Aborted);
  EXPECT_EQ(runs[1].reason, "light curtain interrupted");
  RunFilter failed;
  failed.status = RunStatus::Failed;
  EXPECT_EQ(store->queryRuns(failed).size(), 1u);
}

TEST_P(StoreContract, FiltersTheHistory) {
  const auto store = open();
  store->recordRuns({makeRun("A1", "hood", 1, 8, "good"), makeRun("A2", "hood", 2, 8, "marginal", 6),
                     makeRun("A1", "door", 3, 8, "good"), makeRun("B1", "hood", 4, 8, "failed", -2),
                     makeRun("B2", "door", 5, 8, "marginal", 7)});
  const auto ids = [&](const RunFilter& f) {
    std::string out;
    for (const RunRow& r : store->queryRuns(f)) {
      if (!out.empty()) out += " ";
      out.append(r.part_id).append("/").append(r.program);
    }
    return out;
  };
  EXPECT_EQ(ids({}), "A1/hood A2/hood A1/door B1/hood B2/door");  // oldest first
  RunFilter f;
  f.part_id = "A1";
  EXPECT_EQ(ids(f), "A1/hood A1/door");
  f = {};
  f.program = "hood";
  EXPECT_EQ(ids(f), "A1/hood A2/hood B1/hood");
  f.verdict = "marginal";
  EXPECT_EQ(ids(f), "A2/hood");
  f = {};
  f.since = "2026-11-03";
  EXPECT_EQ(ids(f), "A1/door B1/hood B2/door");
  f.since = "2026-11-04T08:00";
  EXPECT_EQ(ids(f), "B1/hood B2/door");
  f.since = "2026-11-04T08:00:01Z";
  EXPECT_EQ(ids(f), "B2/door");
  f = {};
  f.limit = 2;
  EXPECT_EQ(ids(f), "B1/hood B2/door");  // the newest two, still oldest first
  f = {};
  f.since = "yesterday";
  EXPECT_THROW(store->queryRuns(f), ResultsError);
  f.since = "2026-13-01";
  EXPECT_THROW(store->queryRuns(f), ResultsError);
}

TEST_P(StoreContract, ALockedDatabaseGivesAClearErrorWithinTheLockTimeout) {
  open()->recordRun(makeRun("P1", "hood", 1, 8));
  StoreOptions options;
  options.lock_timeout = std::chrono::milliseconds(300);
  const auto store = open(options);
  const auto lock = backend_->holdWriteLock(where_);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    store->recordRun(makeRun("P2", "hood", 2, 8));
    FAIL() << "recorded into a locked database";
  } catch (const ResultsError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("locked"), std::string::npos) << message;
    EXPECT_NE(message.find("P2"), std::string::npos) << message;  // names the run not recorded
  }
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GE(waited, 0.2);
  EXPECT_LT(waited, 10.0);
}

INSTANTIATE_TEST_SUITE_P(Backends, StoreContract, ::testing::Values("sqlite", "postgres"),
                         [](const auto& param_info) { return param_info.param; });

}  // namespace
}  // namespace stampscan::results
