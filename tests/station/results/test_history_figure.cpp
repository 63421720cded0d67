// The figure of the results history: a query over 100,000 runs in SQLite (goal: under 100 ms).
// The times are printed, not asserted (they depend on the machine); the answers are asserted.
#include "results_test_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>

namespace stampscan::results {
namespace {

double millisecondsOf(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

TEST(HistoryFigure, QueriesOver100000Runs) {
  test::TempDir runs_dir;
  constexpr std::size_t kRuns = 100000, kPrograms = 50;
  std::vector<RunRow> runs;
  runs.reserve(kRuns);
  for (std::size_t k = 0; k < kRuns; ++k) {
    // One part a minute, round the clock, programs in turn.
    RunRow r = test::makeRun(test::numbered("P", k), test::numbered("program-", k % kPrograms), 1, 0);
    char started[32];
    std::snprintf(started, sizeof started, "2026-%02zu-%02zuT%02zu:%02zu:00Z", 1 + k / (60 * 24 * 28), 1 + (k / (60 * 24)) % 28,
                  (k / 60) % 24, k % 60);
    r.started_utc = started;
    r.run_id = std::string(started).append("-P").append(std::to_string(k));
    r.verdict = k % 97 == 0 ? "failed" : k % 13 == 0 ? "marginal" : "good";
    runs.push_back(std::move(r));
  }
  const auto store = openResultsStore(runs_dir.path().string());
  const double write_ms = millisecondsOf([&] { store->recordRuns(runs); });

  StoreOptions read_only;
  read_only.read_only = true;
  std::vector<RunRow> found;
  const double open_ms = millisecondsOf([&] { (void)openResultsStore(runs_dir.path().string(), read_only); });
  const auto reader = openResultsStore(runs_dir.path().string(), read_only);
  RunFilter program;
  program.program = "program-7";
  const double program_ms = millisecondsOf([&] { found = reader->queryRuns(program); });
  EXPECT_EQ(found.size(), kRuns / kPrograms);
  RunFilter recent;
  recent.program = "program-7";
  recent.since = "2026-03-01";
  recent.verdict = "good";
  const double recent_ms = millisecondsOf([&] { found = reader->queryRuns(recent); });
  EXPECT_FALSE(found.empty());
  for (const RunRow& r : found) EXPECT_GE(r.started_utc, "2026-03-01");
  RunFilter last;
  last.limit = 50;
  const double last_ms = millisecondsOf([&] { found = reader->queryRuns(last); });
  ASSERT_EQ(found.size(), 50u);
  EXPECT_EQ(found.back().part_id, test::numbered("P", kRuns - 1));
  const double all_ms = millisecondsOf([&] { found = reader->queryRuns(); });
  EXPECT_EQ(found.size(), kRuns);

  std::printf("[ figure   ] results history, SQLite, %zu runs (written in one transaction in %.0f ms)\n", kRuns, write_ms);
  std::printf("[ figure   ] open read-only %.1f ms; --program (2000 rows) %.1f ms; --program --since --verdict %.1f ms; "
              "newest 50 %.1f ms; all %zu rows %.1f ms (goal: a history query under 100 ms)\n",
              open_ms, program_ms, recent_ms, last_ms, kRuns, all_ms);
}

}  // namespace
}  // namespace stampscan::results
