// The panel's log: plain lines on standard error, which systemd's journal takes with their levels.
// Under systemd (JOURNAL_STREAM is set) each line carries its syslog level as a "<N>" prefix
// (sd-daemon(3)), so that the journal files it as an error, a warning or a notice.
//
// Thread safety: logLine may be called from any thread (one write per line); a HealthLog is used by
// one thread.
#pragma once

#include "stampscan/hmi/cell_health.hpp"

#include <map>
#include <string>

namespace stampscan::hmi {

// syslog levels (syslog(3)) of the lines the panel writes.
inline constexpr int kLogError = 3, kLogWarning = 4, kLogNotice = 5, kLogInfo = 6;

// "station hmi: TEXT" on standard error, one line (line breaks in TEXT become spaces).
void logLine(int syslog_level, std::string text);

// Logs the health's findings when they appear or change, and says when one is mended.
class HealthLog {
 public:
  void update(const CellHealth& health);

 private:
  std::map<std::string, std::string> reported_;  // what -> the line logged for it
};

}  // namespace stampscan::hmi
