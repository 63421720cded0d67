// Calibrations and verifications as rows of the results database (station/results), beside the
// runs: the record's file in the calibration history stays the full account (with its traces), the
// row lets the history be read with the runs, from one place when several cells share a database.
#pragma once

#include "stampscan/registration/calibration_record.hpp"

#include <filesystem>
#include <string>

namespace stampscan::jobs {

// The database a cell's calibrations go to: `configured` (the cell's [results] database: a runs
// folder or a PostgreSQL URL) when set, else the folder that holds the calibration folder (by
// default the runs folder, whose results.sqlite the scans write).
std::string calibrationResultsDatabase(const std::string& configured, const std::filesystem::path& calibration_dir);

// Records (or replaces) the record as a row. Returns why it could not be, "" when it was: the
// record's file is written already, so a database that cannot be written loses nothing.
std::string recordCalibrationInResults(const registration::CalibrationRecord& record,
                                       const std::filesystem::path& record_file, const std::string& database);

}  // namespace stampscan::jobs
