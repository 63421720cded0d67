#include "stampscan/station/commands.hpp"

#include <array>

namespace stampscan::station {

std::span<const CommandEntry> commandTable() {
  static constexpr std::array<CommandEntry, 9> kCommands{{
      {"scan", addScanCommand},
      {"process", addProcessCommand},
      {"report", addReportCommand},
      {"fit", addFitCommand},
      {"devices", addDevicesCommand},
      {"trace", addTraceCommand},
      {"sim", addSimCommand},
      {"sample", addSampleCommand},
      {"demo", addDemoCommand},
  }};
  return kCommands;
}

}  // namespace stampscan::station
