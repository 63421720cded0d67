// A run folder's name: <yyyymmdd>-<hhmmss>-<part id>, the time in UTC when the scan started, the
// part id with every character but letters, digits, '-' and '_' made '_' (and "part" for none).
// The scan names its folders so; the report and the results history read the time and the part back
// from folders whose run.json says nothing of them.
#pragma once

#include <ctime>
#include <optional>
#include <string>

namespace stampscan::run_folder {

std::string runFolderName(const std::string& part_id, std::time_t started);

struct FolderName {
  std::string started_utc;  // ISO 8601, UTC: 2026-11-24T09:16:02Z
  std::string part_id;
};
// Nothing when the name is not of that form.
std::optional<FolderName> parseRunFolderName(const std::string& name);

}  // namespace stampscan::run_folder
