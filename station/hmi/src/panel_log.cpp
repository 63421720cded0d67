#include "stampscan/hmi/panel_log.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

namespace stampscan::hmi {

void logLine(int syslog_level, std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');  // one entry, one line: the level holds for all of it
  std::string line;
  if (std::getenv("JOURNAL_STREAM") != nullptr) {
    line += '<';
    line += std::to_string(syslog_level);
    line += '>';
  }
  line += "station hmi: ";
  line += text;
  line += '\n';
  std::fputs(line.c_str(), stderr);  // one write, not split by other threads' output
  std::fflush(stderr);
}

void HealthLog::update(const CellHealth& health) {
  std::map<std::string, std::string> now;
  for (const HealthFinding& f : health.findings) {
    const std::string line = std::string(toString(f.level)) + ": " + f.text;
    now[f.what] = line;
    if (reported_[f.what] != line) logLine(f.level == HealthLevel::Fault ? kLogError : kLogWarning, line);
  }
  for (const auto& [what, line] : reported_)
    if (!line.empty() && now.count(what) == 0) logLine(kLogInfo, "mended: " + what + " (was " + line + ")");
  reported_ = std::move(now);
}

}  // namespace stampscan::hmi
