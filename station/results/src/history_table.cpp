#include "stampscan/results/history_table.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace stampscan::results {

std::string formatNumber(const std::optional<double>& v, int decimals, const std::string& absent) {
  if (!v || !std::isfinite(*v)) return absent;
  char text[48];
  std::snprintf(text, sizeof text, "%.*f", decimals, *v);
  return text;
}

std::string historyTable(const std::vector<RunRow>& runs) {
  const std::vector<std::string> header = {"started (UTC)", "part", "program", "verdict", "max thin %", "min margin %",
                                           "elements", "status", "run"};
  std::vector<std::vector<std::string>> rows;
  rows.reserve(runs.size());
  for (const RunRow& r : runs) {
    std::string status = toString(r.status);
    if (!r.reason.empty()) status.append(": ").append(r.reason);
    if (!r.data_loss.empty()) status.append(" (data loss: ").append(r.data_loss).append(")");
    rows.push_back({r.started_utc, r.part_id, r.program.empty() ? "-" : r.program, r.verdict.empty() ? "-" : r.verdict,
                    formatNumber(r.max_thinning_percent, 1), formatNumber(r.min_margin_percent, 1),
                    r.elements ? std::to_string(*r.elements) : "-", status, r.run_id});
  }
  // Column widths from the content; the status (with its reason) and the run id go last, unpadded.
  std::vector<std::size_t> width(header.size());
  for (std::size_t c = 0; c < header.size(); ++c) {
    width[c] = header[c].size();
    for (const auto& row : rows) width[c] = std::max(width[c], row[c].size());
  }
  std::string out;
  const auto line = [&](const std::vector<std::string>& cells) {
    for (std::size_t c = 0; c < cells.size(); ++c) {
      const bool numeric = c >= 4 && c <= 6;
      const std::string pad(width[c] - cells[c].size(), ' ');
      out += numeric ? pad + cells[c] : cells[c] + (c + 1 < cells.size() ? pad : "");
      if (c + 1 < cells.size()) out += "  ";
    }
    while (!out.empty() && out.back() == ' ') out.pop_back();
    out += "\n";
  };
  line(header);
  for (const auto& row : rows) line(row);
  return out;
}

namespace {
std::string csvField(const std::string& v) {
  if (v.find_first_of(",\"\n\r") == std::string::npos) return v;
  std::string out = "\"";
  for (char c : v) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}
}  // namespace

std::string historyCsv(const std::vector<RunRow>& runs) {
  std::string out =
      "run_id,part_id,program,plan,cell,started_utc,material,verdict,max_thinning_percent,min_margin_percent,"
      "marginal_band_percent,elements,position_rms_mm,strain_rms,data_loss,run_dir,status,reason\n";
  const auto full = [](const std::optional<double>& v) { return formatNumber(v, 6, ""); };
  for (const RunRow& r : runs) {
    const std::vector<std::string> cells = {r.run_id,
                                            r.part_id,
                                            r.program,
                                            r.plan,
                                            r.cell,
                                            r.started_utc,
                                            r.material,
                                            r.verdict,
                                            full(r.max_thinning_percent),
                                            full(r.min_margin_percent),
                                            full(r.marginal_band_percent),
                                            r.elements ? std::to_string(*r.elements) : "",
                                            full(r.position_rms_mm),
                                            full(r.strain_rms),
                                            r.data_loss,
                                            r.run_dir,
                                            toString(r.status),
                                            r.reason};
    for (std::size_t c = 0; c < cells.size(); ++c) {
      if (c > 0) out += ',';
      out += csvField(cells[c]);
    }
    out += "\n";
  }
  return out;
}

}  // namespace stampscan::results
