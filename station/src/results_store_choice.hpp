// Where `station history` and `station trend` read the results history from: a runs folder (its
// results.sqlite, -o), a PostgreSQL URL (--db), or the database a cell file names (--cell). One set
// of options and one way of opening it, read-only, for both commands.
#pragma once

#include "stampscan/results/results_store.hpp"

#include <CLI/CLI.hpp>

#include <memory>
#include <string>

namespace stampscan::station {

struct ResultsStoreChoice {
  std::string runs = "stampscan-runs", db, cell;

  void addTo(CLI::App* cmd);
  // Resolves --cell into runs or db (a cell file naming no database is refused), then opens the
  // store read-only; `command` names the command in messages.
  std::unique_ptr<results::ResultsStore> openReadOnly(const char* command);
};

}  // namespace stampscan::station
