// `station trend --program P`: max thinning, min safety margin and verdict per part of a program
// over time, as a table and a PNG, with the drift warning of results::analyzeTrend. A thin caller of
// station/results/.
#include "stampscan/results/results_store.hpp"
#include "stampscan/results/trend.hpp"
#include "stampscan/station/commands.hpp"
#include "results_store_choice.hpp"

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <memory>

namespace stampscan::station {

namespace {
struct TrendCommandOptions {
  ResultsStoreChoice store;
  std::string program, png;
  std::size_t window = results::TrendParams{}.window;
};

// trend-<program>.png, the program's name made safe for a file name.
std::string defaultImageName(const std::string& program) {
  std::string name = "trend-";
  for (char c : program) name.push_back(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_');
  return name + ".png";
}
}  // namespace

CommandRunner addTrendCommand(CLI::App& app) {
  auto opt = std::make_shared<TrendCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "trend", "Max thinning, min safety margin and verdict per part of a press program over time (table and PNG), "
               "with a warning when the last parts drift towards the margin");
  cmd->add_option("--program", opt->program, "The press program")->required();
  opt->store.addTo(cmd);
  cmd->add_option("--png", opt->png,
                  "The image to write (default: trend-<program>.png in the runs folder; with --db, here)");
  cmd->add_option("--window", opt->window, "Parts the drift rule looks back (and ahead)")
      ->capture_default_str()
      ->check(CLI::Range(2, 1000));
  return [opt]() {
    const auto store = opt->store.openReadOnly("trend");
    results::RunFilter filter;
    filter.program = opt->program;
    const std::vector<results::RunRow> runs_found = store->queryRuns(filter);
    if (runs_found.empty())
      throw std::runtime_error("trend: no runs of program \"" + opt->program + "\" in " + store->location());
    results::TrendParams params;
    params.window = opt->window;
    const results::TrendAnalysis trend = results::analyzeTrend(runs_found, params);
    const std::filesystem::path image =
        !opt->png.empty()       ? std::filesystem::path(opt->png)
        : opt->store.db.empty() ? std::filesystem::path(opt->store.runs) / defaultImageName(opt->program)
                                : std::filesystem::path(defaultImageName(opt->program));
    results::writeTrendImage(trend, opt->program, image);
    std::printf("station trend --program %s (%s)\n", opt->program.c_str(), store->location().c_str());
    const std::string table = results::trendTable(trend);
    std::fwrite(table.data(), 1, table.size(), stdout);
    if (trend.runs_not_analysed > 0)
      std::printf("  (%zu failed or aborted run(s) of the program not shown: see `station history`)\n",
                  trend.runs_not_analysed);
    std::printf("%s\n%s\nimage: %s\n", trend.message.c_str(), results::describeTrendRule(params).c_str(),
                image.c_str());
    return 0;
  };
}

}  // namespace stampscan::station
