// A run folder (RUNS/<time>-<part-id>/, as `station scan` writes it) as a row of the results
// history: run.json gives the run, report.json (written by `station report`) the verdict and the
// figures. A folder whose run was aborted or whose report is missing or damaged is still recorded,
// as aborted or failed with the reason: no run is lost from the history.
#pragma once

#include "stampscan/results/results_store.hpp"

#include <filesystem>
#include <string>

namespace stampscan::results {

// The row for a run folder. Throws ResultsError only when the folder holds neither run.json nor
// report.json (it is not a run folder).
RunRow readRunRow(const std::filesystem::path& run_dir);

// Records (or updates) the run in the database of `runs_dir_or_url`: a runs folder (its
// results.sqlite, created when missing) or a postgresql:// URL. A non-empty `failure_reason` (the
// processing that failed, e.g. the report's error) records the run as failed with that reason.
// Returns the row written; throws ResultsError naming the database when it cannot be written.
RunRow recordRunInResults(const std::filesystem::path& run_dir, const std::string& runs_dir_or_url,
                             const std::string& failure_reason = {});
// The same, in the database of the runs folder that holds the run folder.
RunRow recordRunInResults(const std::filesystem::path& run_dir);

}  // namespace stampscan::results
