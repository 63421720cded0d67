#include "results_store_choice.hpp"

#include "stampscan/acquisition/cell_config.hpp"

#include <stdexcept>

namespace stampscan::station {

void ResultsStoreChoice::addTo(CLI::App* cmd) {
  CLI::Option* runs_option =
      cmd->add_option("-o,--runs", runs, "Folder of run folders, holding results.sqlite")->capture_default_str();
  CLI::Option* db_option =
      cmd->add_option("--db", db, "A PostgreSQL results database instead (postgresql://...)")->excludes(runs_option);
  cmd->add_option("--cell", cell, "The results database the cell file names ([results] database)")
      ->excludes(runs_option)
      ->excludes(db_option);
}

std::unique_ptr<results::ResultsStore> ResultsStoreChoice::openReadOnly(const char* command) {
  if (!db.empty() && !results::isDatabaseUrl(db))
    throw std::runtime_error(std::string(command) + ": --db " + db + ": expected a postgresql:// URL");
  if (!cell.empty()) {
    const std::string configured = acquisition::loadCellConfig(cell).results_database;
    if (configured.empty())
      throw std::runtime_error(cell + ": names no results database ([results] database): pass -o RUNS_DIR");
    (results::isDatabaseUrl(configured) ? db : runs) = configured;
  }
  results::StoreOptions options;
  options.read_only = true;
  return results::openResultsStore(db.empty() ? runs : db, options);
}

}  // namespace stampscan::station
