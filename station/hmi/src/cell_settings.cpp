#include "stampscan/hmi/cell_settings.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>

namespace stampscan::hmi {

namespace fs = std::filesystem;

const std::vector<SettingRange>& cellSettingRanges() {
  // Ranges wide enough for any real cell, narrow enough to catch a slip of the finger (a validity of
  // 7000 days, an MPE in micrometres typed as millimetres).
  static const std::vector<SettingRange> ranges = {
      {"validity_days", "days", 0.1, 365, "a scan refuses a calibration older than this"},
      {"digitizer_residual_mm", "mm", 0.001, 0.5, "a new digitizer calibration is accepted at or below this sphere residual"},
      {"form_mpe_mm", "mm", 0.001, 1.0, "the verification's MPE of the probing form error"},
      {"size_mpe_mm", "mm", 0.001, 1.0, "the verification's MPE of the probing size error"},
  };
  return ranges;
}

namespace {

double* field(acquisition::CalibrationPolicy& p, const std::string& key) {
  if (key == "validity_days") return &p.validity_days;
  if (key == "digitizer_residual_mm") return &p.digitizer_residual_mm;
  if (key == "form_mpe_mm") return &p.form_mpe_mm;
  if (key == "size_mpe_mm") return &p.size_mpe_mm;
  return nullptr;
}

// A value as the cell file writes it: no exponent, no trailing zeros beyond what it needs.
std::string tomlNumber(double v) {
  char text[64];
  std::snprintf(text, sizeof text, "%.6f", v);
  std::string s = text;
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.push_back('0');
  return s;
}

}  // namespace

std::map<std::string, double> settingsOf(const acquisition::CalibrationPolicy& policy) {
  acquisition::CalibrationPolicy p = policy;
  std::map<std::string, double> out;
  for (const auto& r : cellSettingRanges()) out[r.key] = *field(p, r.key);
  return out;
}

acquisition::CalibrationPolicy withSettings(acquisition::CalibrationPolicy policy, const std::map<std::string, double>& changes) {
  for (const auto& [key, value] : changes) {
    const SettingRange* range = nullptr;
    for (const auto& r : cellSettingRanges())
      if (key == r.key) range = &r;
    if (range == nullptr) {
      std::string known;
      for (const auto& r : cellSettingRanges()) known += (known.empty() ? "" : ", ") + std::string(r.key);
      throw SettingsError("no setting '" + key + "' (the panel sets " + known + ")");
    }
    if (!std::isfinite(value) || value < range->min || value > range->max)
      throw SettingsError("'" + key + "' must be " + tomlNumber(range->min) + "-" + tomlNumber(range->max) + " " +
                          range->unit + ", not " + tomlNumber(value));
    *field(policy, key) = value;
  }
  return policy;
}

void writeCellSettings(const fs::path& cell_file, const std::map<std::string, double>& changes) {
  std::ifstream in(cell_file);
  if (!in) throw std::runtime_error(cell_file.string() + ": cannot be read to change its settings");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);

  // The [calibration] table: from its header to the next header (or the end).
  const std::regex header(R"(^\s*\[\s*([A-Za-z0-9_.\-]+)\s*\]\s*(#.*)?$)");
  std::size_t begin = lines.size(), end = lines.size();
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::smatch m;
    if (!std::regex_match(lines[i], m, header)) continue;
    if (begin == lines.size() && m[1] == "calibration") begin = i;
    else if (begin != lines.size()) {
      end = i;
      break;
    }
  }
  if (begin == lines.size()) {
    lines.push_back("");
    lines.push_back("[calibration]");
    begin = lines.size() - 1;
    end = lines.size();
  }
  for (const auto& [key, value] : changes) {
    // `key = value   # comment`: the value is replaced, the comment kept.
    const std::regex entry("^(\\s*" + key + "\\s*=\\s*)([^#]*?)(\\s*#.*)?$");
    bool found = false;
    for (std::size_t i = begin + 1; i < end && !found; ++i) {
      std::smatch m;
      if (std::regex_match(lines[i], m, entry)) {
        lines[i] = m[1].str() + tomlNumber(value) + m[3].str();
        found = true;
      }
    }
    if (!found) {
      lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(begin) + 1, key + " = " + tomlNumber(value));
      ++end;
    }
  }
  std::ostringstream text;
  for (const auto& l : lines) text << l << '\n';

  fitting::AtomicFile out(cell_file);
  {
    std::ofstream tmp(out.temporaryPath());
    tmp << text.str();
    if (!tmp.flush()) throw std::runtime_error(cell_file.string() + ": cannot write the changed settings");
  }
  // Read back as every command reads it before it replaces the file the cell runs on.
  acquisition::CellConfig check;
  try {
    check = acquisition::loadCellConfig(out.temporaryPath());
  } catch (const std::exception& e) {
    throw std::runtime_error(cell_file.string() + ": the changed file would not load (" + e.what() + "); left as it was");
  }
  for (const auto& [key, value] : changes)
    if (const double* v = field(check.calibration, key); v == nullptr || std::abs(*v - value) > 1e-9 * std::max(1.0, value))
      throw std::runtime_error(cell_file.string() + ": '" + key + "' did not read back as written; left as it was");
  out.commit();
}

}  // namespace stampscan::hmi
