// `station history` and `station trend` end to end on a runs folder, and `station report`
// recording the run in the runs folder's database.
#include "results_test_support.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdio>

namespace stampscan::results {
namespace {

using test::makeRun;

struct Output {
  int status;
  std::string text;
};

Output run(const std::string& arguments) {
  const std::string command = std::string(STATION_EXE) + " " + arguments + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  Output out{-1, {}};
  if (!pipe) return out;
  std::array<char, 4096> buffer;
  while (const std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) out.text.append(buffer.data(), n);
  const int status = pclose(pipe);
  out.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return out;
}

class HistoryCommands : public ::testing::Test {
 protected:
  void SetUp() override {
    std::vector<RunRow> runs;
    const double margins[] = {30, 30, 20, 18, 16, 14, 12};
    for (int k = 0; k < 7; ++k)
      runs.push_back(makeRun(test::numbered("H", static_cast<std::size_t>(k + 1)), "hood", k + 1, 8, "good", margins[k]));
    runs.push_back(makeRun("D1", "door", 2, 9, "marginal", 6));
    openResultsStore(runs_.path().string())->recordRuns(runs);
  }
  std::string runs() const { return runs_.path().string(); }
  test::TempDir runs_;
};

TEST_F(HistoryCommands, HistoryFiltersAndExportsCsv) {
  const Output all = run("history -o " + runs());
  ASSERT_EQ(all.status, 0) << all.text;
  EXPECT_NE(all.text.find("8 run(s)"), std::string::npos) << all.text;
  const Output door = run("history -o " + runs() + " --program door --csv");
  ASSERT_EQ(door.status, 0) << door.text;
  EXPECT_EQ(door.text.find("run_id,part_id,program"), 0u) << door.text;
  EXPECT_NE(door.text.find("\n20261102-090000-D1,D1,door,"), std::string::npos) << door.text;
  EXPECT_EQ(door.text.find(",hood,"), std::string::npos) << door.text;
  const Output since = run("history -o " + runs() + " --since 2026-11-06 --verdict good");
  EXPECT_NE(since.text.find("2 run(s)"), std::string::npos) << since.text;
  const Output bad = run("history -o " + runs() + " --since last-week");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.text.find("--since \"last-week\""), std::string::npos) << bad.text;
}

TEST_F(HistoryCommands, HistoryOfAFolderWithoutDatabaseFailsClearly) {
  test::TempDir empty;
  const Output out = run("history -o " + empty.path().string());
  EXPECT_EQ(out.status, 1);
  EXPECT_NE(out.text.find("no results database"), std::string::npos) << out.text;
  EXPECT_FALSE(std::filesystem::exists(empty.path() / kSqliteFileName));
}

TEST_F(HistoryCommands, TrendWarnsAndWritesTheImage) {
  const Output out = run("trend --program hood -o " + runs());
  ASSERT_EQ(out.status, 0) << out.text;
  EXPECT_NE(out.text.find("WARNING: min safety margin falling"), std::string::npos) << out.text;
  EXPECT_NE(out.text.find("rule: least-squares slope"), std::string::npos) << out.text;
  EXPECT_TRUE(std::filesystem::exists(runs_.path() / "trend-hood.png"));
  const Output none = run("trend --program press-9 -o " + runs());
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.text.find("no runs of program \"press-9\""), std::string::npos) << none.text;
}

}  // namespace
}  // namespace stampscan::results
