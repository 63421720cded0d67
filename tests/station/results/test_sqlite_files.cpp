// What only an SQLite file can be: read-only, damaged, missing; and a runs folder that is not there.
#include "results_test_support.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

namespace stampscan::results {
namespace {

using test::makeRun;

std::string messageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const ResultsError& e) {
    return e.what();
  }
  return "(no error)";
}

// Root writes any file whatever its mode: the test takes the nobody user's rights for its scope.
class AsUnprivilegedUser {
 public:
  AsUnprivilegedUser() {
    if (geteuid() != 0) return;
    dropped_ = seteuid(65534) == 0;  // nobody
    failed_ = !dropped_;
  }
  ~AsUnprivilegedUser() {
    if (dropped_) [[maybe_unused]] const int ignored = seteuid(0);
  }
  AsUnprivilegedUser(const AsUnprivilegedUser&) = delete;
  AsUnprivilegedUser& operator=(const AsUnprivilegedUser&) = delete;
  bool failed() const { return failed_; }

 private:
  bool dropped_ = false, failed_ = false;
};

TEST(SqliteFiles, AReadOnlyDatabaseIsReadButNotWritten) {
  test::TempDir runs;
  openResultsStore(runs.path().string())->recordRun(makeRun("P1", "hood", 1, 8));
  const auto file = runs.path() / kSqliteFileName;
  std::filesystem::permissions(file, std::filesystem::perms::owner_read | std::filesystem::perms::group_read |
                                         std::filesystem::perms::others_read);
  std::filesystem::permissions(runs.path(), std::filesystem::perms::owner_all | std::filesystem::perms::group_read |
                                                std::filesystem::perms::group_exec | std::filesystem::perms::others_read |
                                                std::filesystem::perms::others_exec);
  AsUnprivilegedUser user;
  if (user.failed()) GTEST_SKIP() << "running as root and cannot take another user's rights (seteuid failed)";
  const std::string message = messageOf([&] { openResultsStore(runs.path().string()); });
  EXPECT_NE(message.find("read-only"), std::string::npos) << message;
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;
  StoreOptions read_only;
  read_only.read_only = true;
  EXPECT_EQ(openResultsStore(runs.path().string(), read_only)->queryRuns().size(), 1u);
}

TEST(SqliteFiles, ADamagedFileIsNamedAndLeftAsItWas) {
  test::TempDir runs;
  const auto file = runs.path() / kSqliteFileName;
  std::ofstream(file) << "this is not a database, but a note somebody saved here\n";
  const auto size = std::filesystem::file_size(file);
  const std::string message = messageOf([&] { openResultsStore(runs.path().string()); });
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;
  EXPECT_NE(message.find("not an SQLite database"), std::string::npos) << message;
  EXPECT_EQ(std::filesystem::file_size(file), size);
}

TEST(SqliteFiles, ReadingARunsFolderWithoutADatabaseSaysSoAndCreatesNothing) {
  test::TempDir runs;
  StoreOptions read_only;
  read_only.read_only = true;
  const std::string message = messageOf([&] { openResultsStore(runs.path().string(), read_only); });
  EXPECT_NE(message.find("no results database"), std::string::npos) << message;
  EXPECT_FALSE(std::filesystem::exists(runs.path() / kSqliteFileName));
  const std::string missing = messageOf([&] { openResultsStore((runs.path() / "nowhere").string()); });
  EXPECT_NE(missing.find("not a runs folder"), std::string::npos) << missing;
}

TEST(SqliteFiles, ABatchWithABadRecordWritesNoneOfIt) {
  test::TempDir runs;
  const auto store = openResultsStore(runs.path().string());
  RunRow bad = makeRun("P3", "hood", 1, 10);
  bad.started_utc.clear();
  EXPECT_THROW(store->recordRuns({makeRun("P1", "hood", 1, 8), makeRun("P2", "hood", 1, 9), bad}), ResultsError);
  EXPECT_TRUE(store->queryRuns().empty());
}

}  // namespace
}  // namespace stampscan::results
