// Run folders as rows: what run.json and report.json give, and runs that were aborted, not
// analysed or damaged recorded as such with their reason.
#include "results_test_support.hpp"
#include "stampscan/results/run_recording.hpp"

#include <gtest/gtest.h>

namespace stampscan::results {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json runJson() {
  return {{"part_id", "D-0042"},
          {"plan", "dome"},
          {"cell", "virtual"},
          {"completed", true},
          {"program", "dome-50"},
          {"material", "DC04"},
          {"measurement", {{"elements", 1180}}},
          {"accuracy", {{"matched", 1100}, {"position_rms_mm", 0.031}, {"strain_rms", 0.0042}}},
          {"data_loss", nullptr}};
}

json reportJson() {
  return {{"part_id", "D-0042"},
          {"program", "dome-50"},
          {"material", "DC04"},
          {"safety_margin_percent", 10.0},
          {"verdict", "marginal"},
          {"elements", 1180},
          {"max_thinning_percent", 23.4},
          {"min_margin_percent", 6.2}};
}

class RunRecording : public ::testing::Test {
 protected:
  fs::path runFolder(const std::string& name = "20261124-091602-D-0042") {
    const fs::path dir = runs_.path() / name;
    fs::create_directories(dir);
    return dir;
  }
  std::vector<RunRow> history() {
    return openResultsStore(runs_.path().string())->queryRuns();
  }
  test::TempDir runs_;
};

TEST_F(RunRecording, AReportedRunIsRecordedWithItsFigures) {
  const fs::path dir = runFolder();
  test::writeJson(dir / "run.json", runJson());
  test::writeJson(dir / "report.json", reportJson());
  recordRunInResults(dir);
  const auto runs = history();
  ASSERT_EQ(runs.size(), 1u);
  const RunRow& r = runs[0];
  EXPECT_EQ(r.run_id, "20261124-091602-D-0042");
  EXPECT_EQ(r.part_id, "D-0042");
  EXPECT_EQ(r.program, "dome-50");
  EXPECT_EQ(r.plan, "dome");
  EXPECT_EQ(r.cell, "virtual");
  EXPECT_EQ(r.started_utc, "2026-11-24T09:16:02Z");
  EXPECT_EQ(r.material, "DC04");
  EXPECT_EQ(r.verdict, "marginal");
  EXPECT_DOUBLE_EQ(*r.max_thinning_percent, 23.4);
  EXPECT_DOUBLE_EQ(*r.min_margin_percent, 6.2);
  EXPECT_DOUBLE_EQ(*r.marginal_band_percent, 10.0);
  EXPECT_EQ(*r.elements, 1180);
  EXPECT_DOUBLE_EQ(*r.position_rms_mm, 0.031);
  EXPECT_DOUBLE_EQ(*r.strain_rms, 0.0042);
  EXPECT_EQ(r.data_loss, "");
  EXPECT_EQ(fs::path(r.run_dir), dir);
  EXPECT_EQ(r.status, RunStatus::Ok);

  // The report run again with another verdict: the row is updated, not doubled.
  json again = reportJson();
  again["verdict"] = "good";
  test::writeJson(dir / "report.json", again);
  recordRunInResults(dir.string() + "/");
  ASSERT_EQ(history().size(), 1u);
  EXPECT_EQ(history()[0].verdict, "good");
}

TEST_F(RunRecording, ARunWithoutAReportIsRecordedAsFailed) {
  const fs::path dir = runFolder();
  test::writeJson(dir / "run.json", runJson());
  const RunRow r = recordRunInResults(dir, runs_.path().string());
  EXPECT_EQ(r.status, RunStatus::Failed);
  EXPECT_NE(r.reason.find("no report.json"), std::string::npos) << r.reason;
  // The scan's report error, when it gives one, is the reason.
  const RunRow with_reason =
      recordRunInResults(dir, runs_.path().string(), "cloud4d.ply: damaged (truncated at byte 4096)");
  EXPECT_EQ(with_reason.reason, "cloud4d.ply: damaged (truncated at byte 4096)");
  ASSERT_EQ(history().size(), 1u);
  EXPECT_EQ(history()[0].status, RunStatus::Failed);
  EXPECT_EQ(history()[0].reason, "cloud4d.ply: damaged (truncated at byte 4096)");
}

TEST_F(RunRecording, AnAbortedScanIsRecordedAsAbortedWithItsReason) {
  const fs::path dir = runFolder("20261124-100000-D-0043");
  json run = runJson();
  run["completed"] = false;
  run["abort_reason"] = "operator stop";
  test::writeJson(dir / "run.json", run);
  recordRunInResults(dir);
  ASSERT_EQ(history().size(), 1u);
  EXPECT_EQ(history()[0].status, RunStatus::Aborted);
  EXPECT_EQ(history()[0].reason, "operator stop");
}

TEST_F(RunRecording, ADamagedReportIsRecordedAsFailedNotLost) {
  const fs::path dir = runFolder();
  test::writeJson(dir / "run.json", runJson());
  std::ofstream(dir / "report.json") << "{\"verdict\": \"go";
  const RunRow r = recordRunInResults(dir);
  EXPECT_EQ(r.status, RunStatus::Failed);
  EXPECT_NE(r.reason.find("report.json is damaged"), std::string::npos) << r.reason;
  EXPECT_EQ(history().size(), 1u);
}

TEST_F(RunRecording, AFolderThatIsNoRunFolderIsRefused) {
  const fs::path dir = runFolder("notes");
  EXPECT_THROW(recordRunInResults(dir), ResultsError);
  EXPECT_FALSE(fs::exists(runs_.path() / kSqliteFileName));
}

}  // namespace
}  // namespace stampscan::results
