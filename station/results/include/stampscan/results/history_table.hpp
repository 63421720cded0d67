// The history as the operator reads it (an aligned text table) and as a spreadsheet reads it (CSV,
// RFC 4180: every column of the row, quoted where a value needs it).
#pragma once

#include "stampscan/results/results_store.hpp"

#include <string>
#include <vector>

namespace stampscan::results {

// One line per run: start, part, program, verdict, figures, status and reason.
std::string historyTable(const std::vector<RunRow>& runs);
// A header line, then one line per run; numbers with full precision, empty cells when absent.
std::string historyCsv(const std::vector<RunRow>& runs);
// A number with `decimals` decimals, or `absent` when there is none.
std::string formatNumber(const std::optional<double>& v, int decimals, const std::string& absent = "-");

}  // namespace stampscan::results
