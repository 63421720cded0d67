// `station history`: the runs of the results history, as a table or CSV. A thin caller of
// station/results/.
#include "stampscan/results/history_table.hpp"
#include "stampscan/results/results_store.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/station/commands.hpp"

#include <cstdio>
#include <memory>

namespace stampscan::station {

namespace {
struct HistoryCommandOptions {
  std::string runs = "stampscan-runs", db, cell, part_id, program, since, verdict;
  std::size_t last = 0;
  bool csv = false;
};
}  // namespace

CommandRunner addHistoryCommand(CLI::App& app) {
  auto opt = std::make_shared<HistoryCommandOptions>();
  CLI::App* cmd = app.add_subcommand("history", "The recorded runs (results history): a table, or CSV with --csv");
  CLI::Option* runs = cmd->add_option("-o,--runs", opt->runs, "Folder of run folders, holding results.sqlite")
                          ->capture_default_str();
  CLI::Option* db = cmd->add_option("--db", opt->db, "A PostgreSQL results database instead (postgresql://...)")->excludes(runs);
  cmd->add_option("--cell", opt->cell, "The results database the cell file names ([results] database)")
      ->excludes(runs)
      ->excludes(db);
  cmd->add_option("--part-id", opt->part_id, "Only this part");
  cmd->add_option("--program", opt->program, "Only this press program");
  cmd->add_option("--since", opt->since, "Only runs started at or after this UTC date or time (2026-11-01[T06:00])");
  cmd->add_option("--verdict", opt->verdict, "Only this verdict")->check(CLI::IsMember({"good", "marginal", "failed"}));
  cmd->add_option("--last", opt->last, "Only the newest N runs (0: all)");
  cmd->add_flag("--csv", opt->csv, "CSV on standard output, every column, for a spreadsheet");
  return [opt]() {
    if (!opt->db.empty() && !results::isDatabaseUrl(opt->db))
      throw std::runtime_error("history: --db " + opt->db + ": expected a postgresql:// URL");
    if (!opt->cell.empty()) {
      const std::string configured = acquisition::loadCellConfig(opt->cell).results_database;
      if (configured.empty())
        throw std::runtime_error(opt->cell + ": names no results database ([results] database): pass -o RUNS_DIR");
      (results::isDatabaseUrl(configured) ? opt->db : opt->runs) = configured;
    }
    results::StoreOptions store_options;
    store_options.read_only = true;
    const auto store = results::openResultsStore(opt->db.empty() ? opt->runs : opt->db, store_options);
    results::RunFilter filter;
    filter.part_id = opt->part_id;
    filter.program = opt->program;
    filter.since = opt->since;
    filter.verdict = opt->verdict;
    filter.limit = opt->last;
    const std::vector<results::RunRecord> runs_found = store->queryRuns(filter);
    const std::string out = opt->csv ? results::historyCsv(runs_found) : results::historyTable(runs_found);
    std::fwrite(out.data(), 1, out.size(), stdout);
    if (!opt->csv) std::printf("%zu run(s) in %s\n", runs_found.size(), store->location().c_str());
    return 0;
  };
}

}  // namespace stampscan::station
