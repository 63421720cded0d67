// The arrows of ARCHITECTURE.md that the station's own folders could break unseen: above the
// drivers nothing takes the cell's geometry or the part from the simulator. Only the hosting of the
// virtual cell (station/src/virtual_cell/: its world built from the cell file, the simulator's own
// commands, scoring against its truth) includes sim/; the libraries below the commands (jobs, the
// panel, the run folder, the report, the results) include nothing of the application's folder.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

// Every `#include` line of the C++ files under `dir` that matches `pattern`, as "file:line: text",
// leaving out the files under `allowed` (empty: none).
std::vector<std::string> includesMatching(const fs::path& dir, const std::regex& pattern, const fs::path& allowed = {}) {
  std::vector<std::string> found;
  for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (!e.is_regular_file() || (ext != ".cpp" && ext != ".hpp")) continue;
    if (!allowed.empty() && e.path().string().rfind(allowed.string(), 0) == 0) continue;
    std::ifstream in(e.path());
    std::string line;
    for (int number = 1; std::getline(in, line); ++number)
      if (line.rfind("#include", 0) == 0 && std::regex_search(line, pattern))
        found.push_back(e.path().string() + ":" + std::to_string(number) + ": " + line);
  }
  return found;
}

const fs::path kStation = fs::path(STAMPSCAN_SOURCE_DIR) / "station";

TEST(Layering, OnlyTheVirtualCellsHostingIncludesTheSimulator) {
  const std::regex sim(R"(["<](stampscan/)?sim/)");
  const std::vector<std::string> found = includesMatching(kStation, sim, kStation / "src" / "virtual_cell");
  EXPECT_TRUE(found.empty()) << "sim/ included outside station/src/virtual_cell/:\n"
                             << [&] {
                                  std::string all;
                                  for (const std::string& f : found) all += "  " + f + "\n";
                                  return all;
                                }();
}

TEST(Layering, TheLibrariesBelowTheCommandsIncludeNothingOfTheApplication) {
  const std::regex application(R"(["<](\.\./)+src/|station/src/|stampscan/station/)");
  for (const char* library : {"jobs", "hmi", "run_folder", "report", "results"}) {
    const std::vector<std::string> found = includesMatching(kStation / library, application);
    EXPECT_TRUE(found.empty()) << "station/" << library << " includes from the application: " << found.front();
  }
}

TEST(Layering, TheCheckSeesTheHostingsOwnIncludes) {
  // The rule above passes on an empty tree too: the hosting itself must be where it is looked for.
  const std::regex sim(R"(["<](stampscan/)?sim/)");
  EXPECT_FALSE(includesMatching(kStation / "src" / "virtual_cell", sim).empty());
}

}  // namespace
