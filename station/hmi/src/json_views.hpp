// The JSON the API and the events show of the cell and its runs (private to the panel library).
#pragma once

#include "stampscan/acquisition/cell.hpp"
#include "stampscan/hmi/cell_jobs.hpp"
#include "stampscan/hmi/line_handshake.hpp"
#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/results/results_store.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>

namespace stampscan::hmi {

// Every device: name, family, state, identity, last fault.
nlohmann::json devicesJson(acquisition::Cell& cell);
// The devices, the interlocks and stack light as the PLC reports them (read now when the PLC is
// connected and idle; else its watchdog's last reading), the calibration in use and its verdict.
nlohmann::json cellJson(const CellJobs& jobs);
// A record's checks against their limits, as the page shows them.
nlohmann::json checksJson(const std::vector<registration::RecordCheck>& checks);
// The calibration in use (each sensor as a scan would judge it, on this cell's rules) and the last records.
nlohmann::json calibrationJson(const std::filesystem::path& calibration_dir, const acquisition::CellConfig& cell);
// The cell's config with the calibration rules the jobs apply now (maintenance may have changed them).
acquisition::CellConfig configInUse(const CellJobs& jobs);
nlohmann::json runRowJson(const results::RunRow& r);
nlohmann::json statusJson(const JobStatus& s);
// The cell's answer to the line, by the names of REGISTER_MAP.md's tables; and the whole handshake.
nlohmann::json lineAnswerJson(const drivers::plc::CellAnswer& a);
nlohmann::json lineJson(const LineState& line);

}  // namespace stampscan::hmi
