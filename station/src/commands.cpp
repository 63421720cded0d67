#include "stampscan/station/commands.hpp"

#include <array>

namespace stampscan::station {

std::span<const CommandEntry> commandTable() {
  static constexpr std::array<CommandEntry, 17> kCommands{{
      {"scan", addScanCommand},
      {"plan", addPlanCommand},
      {"process", addProcessCommand},
      {"report", addReportCommand},
      {"hmi", addHmiCommand},
      {"history", addHistoryCommand},
      {"trend", addTrendCommand},
      {"fit", addFitCommand},
      {"devices", addDevicesCommand},
      {"calibrate", addCalibrateCommand},
      {"verify", addVerifyCommand},
      {"calibration", addCalibrationCommand},
      {"cell", addCellCommand},
      {"trace", addTraceCommand},
      {"sim", addSimCommand},
      {"sample", addSampleCommand},
      {"demo", addDemoCommand},
  }};
  return kCommands;
}

}  // namespace stampscan::station
