// The virtual PLC's program: the interlock rules of drivers/plc/REGISTER_MAP.md applied to the
// register image that libmodbus serves. Not thread-safe: the caller holds the image's mutex.
#pragma once

#include <chrono>
#include <cstdint>

#include <modbus.h>

#include "stampscan/sim/virtual_plc.hpp"

namespace stampscan::sim::detail {

class PlcLogic {
 public:
  using Clock = std::chrono::steady_clock;

  // Fills the image with a healthy, idle cell (see VirtualPlc's constructor).
  PlcLogic(modbus_mapping_t& image, const VirtualPlcOptions& options, Clock::time_point now);

  // Runs the program once over the image. Called after every change (a client's request, an input
  // set by a test) so that its effects are visible at once, and every cycle for the watchdog.
  void evaluate(Clock::time_point now);
  // One logic cycle: counts plc_heartbeat, then evaluates.
  void cycle(Clock::time_point now);

  std::uint64_t stationHeartbeatChanges() const { return heartbeat_changes_; }

 private:
  modbus_mapping_t& image_;
  std::uint16_t last_station_heartbeat_ = 0;
  Clock::time_point last_heartbeat_change_;
  // The watchdog starts with the first heartbeat: a PLC powered up before the station has nobody
  // to watch yet, and tripping then would only force every start-up through a reset.
  bool heartbeat_armed_ = false;
  bool last_clamp_request_ = false;
  std::uint64_t heartbeat_changes_ = 0;
};

}  // namespace stampscan::sim::detail
