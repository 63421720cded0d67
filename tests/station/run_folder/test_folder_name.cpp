#include "stampscan/run_folder/folder_name.hpp"

#include <gtest/gtest.h>

using stampscan::run_folder::parseRunFolderName;
using stampscan::run_folder::runFolderName;

TEST(RunFolderName, IsTheStartInUtcAndThePartIdMadeSafe) {
  const std::time_t t = 1795510800;  // 2026-11-24T09:00:00Z
  EXPECT_EQ(runFolderName("P-4711/a b", t), "20261124-090000-P-4711_a_b");
  EXPECT_EQ(runFolderName("", t), "20261124-090000-part");
}

TEST(RunFolderName, IsReadBack) {
  const auto name = parseRunFolderName(runFolderName("P_1", 1795510800));
  ASSERT_TRUE(name);
  EXPECT_EQ(name->started_utc, "2026-11-24T09:00:00Z");
  EXPECT_EQ(name->part_id, "P_1");
  EXPECT_FALSE(parseRunFolderName("calibration"));
  EXPECT_FALSE(parseRunFolderName("2026112-090000-x"));
}
