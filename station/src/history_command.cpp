// `station history`: the runs of the results history, as a table or CSV. A thin caller of
// station/results/.
#include "stampscan/results/history_table.hpp"
#include "stampscan/results/results_store.hpp"
#include "stampscan/station/commands.hpp"
#include "results_store_choice.hpp"

#include <cstdio>
#include <memory>

namespace stampscan::station {

namespace {
struct HistoryCommandOptions {
  ResultsStoreChoice store;
  std::string part_id, program, since, verdict;
  std::size_t last = 0;
  bool csv = false;
};
}  // namespace

CommandRunner addHistoryCommand(CLI::App& app) {
  auto opt = std::make_shared<HistoryCommandOptions>();
  CLI::App* cmd = app.add_subcommand("history", "The recorded runs (results history): a table, or CSV with --csv");
  opt->store.addTo(cmd);
  cmd->add_option("--part-id", opt->part_id, "Only this part");
  cmd->add_option("--program", opt->program, "Only this press program");
  cmd->add_option("--since", opt->since, "Only runs started at or after this UTC date or time (2026-11-01[T06:00])");
  cmd->add_option("--verdict", opt->verdict, "Only this verdict")->check(CLI::IsMember({"good", "marginal", "failed"}));
  cmd->add_option("--last", opt->last, "Only the newest N runs (0: all)");
  cmd->add_flag("--csv", opt->csv, "CSV on standard output, every column, for a spreadsheet");
  return [opt]() {
    const auto store = opt->store.openReadOnly("history");
    results::RunFilter filter;
    filter.part_id = opt->part_id;
    filter.program = opt->program;
    filter.since = opt->since;
    filter.verdict = opt->verdict;
    filter.limit = opt->last;
    const std::vector<results::RunRow> runs_found = store->queryRuns(filter);
    const std::string out = opt->csv ? results::historyCsv(runs_found) : results::historyTable(runs_found);
    std::fwrite(out.data(), 1, out.size(), stdout);
    if (!opt->csv) std::printf("%zu run(s) in %s\n", runs_found.size(), store->location().c_str());
    return 0;
  };
}

}  // namespace stampscan::station
