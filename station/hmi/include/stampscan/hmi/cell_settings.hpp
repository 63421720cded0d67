// The cell settings maintenance may change on the panel: a small set of the cell file's
// [calibration] keys, each of which the panel's own jobs apply at once.
//
//   validity_days          a scan refuses a calibration older than this (the scan's check, the
//                          calibration status the panel shows)
//   digitizer_residual_mm  a new digitizer calibration is accepted at or below this (Calibrate)
//   form_mpe_mm            the verification's MPE of the probing form error (Verify)
//   size_mpe_mm            the verification's MPE of the probing size error (Verify)
//
// Left out on purpose: the results database (a running panel, its history and the runs it has
// written would point at two databases) and the material library (a file of the plant's, edited
// and reviewed as a file).
//
// When the cell comes from a file (`--cell`), a change is written into that file's [calibration]
// table (only the changed lines; comments and the rest stay as they are; written to a temporary
// and renamed), so `station scan --cell`, `calibrate` and `verify` see it too. The built-in
// virtual cell has no file: there a change holds until the panel stops.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"

#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::hmi {

struct SettingRange {
  const char* key;
  const char* unit;
  double min, max;
  const char* what;
};
// The keys above with the values accepted for each.
const std::vector<SettingRange>& cellSettingRanges();

// The settings' values in a policy, by key.
std::map<std::string, double> settingsOf(const acquisition::CalibrationPolicy& policy);

class SettingsError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};
// The policy with the changes applied. Throws SettingsError naming the key for an unknown key or a
// value out of its range.
acquisition::CalibrationPolicy withSettings(acquisition::CalibrationPolicy policy, const std::map<std::string, double>& changes);

// Writes the changes into the cell file's [calibration] table, then reads the file back
// (acquisition::loadCellConfig) before it replaces the old one. Throws std::runtime_error naming
// the file when it cannot be read, written or would not load.
void writeCellSettings(const std::filesystem::path& cell_file, const std::map<std::string, double>& changes);

}  // namespace stampscan::hmi
