// The station's side of the cell's safety: when the PLC reports the door opened, the e-stop chain
// broken, the light curtain interrupted or its interlock tripped, the CMM's motion is aborted at
// once and the event is logged. (The PLC itself closes the laser shutter and drops motion enable;
// this stops the move the station commanded, so the scan does not wait for a move that cannot end.)
#pragma once

#include "stampscan/acquisition/scan_fault.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/drivers/plc/modbus_plc.hpp"

#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace stampscan::acquisition {

struct SafetyEvent {
  std::chrono::system_clock::time_point when;
  std::string what;  // e.g. "door opened: motion aborted"
  FaultKind kind = FaultKind::Other;
};

class SafetyInterlock {
 public:
  // Registers itself as the PLC driver's event callback, and removes it when destroyed. Both
  // devices must outlive it (an event already under way may still abort the CMM just after).
  SafetyInterlock(drivers::plc::ModbusPlc& plc, drivers::cmm::IppCmm& cmm);
  ~SafetyInterlock();
  SafetyInterlock(const SafetyInterlock&) = delete;
  SafetyInterlock& operator=(const SafetyInterlock&) = delete;

  std::vector<SafetyEvent> events() const;
  bool tripped() const;  // since construction or the last reset()
  void reset();

 private:
  struct State;
  drivers::plc::ModbusPlc& plc_;
  std::shared_ptr<State> state_;
};

}  // namespace stampscan::acquisition
