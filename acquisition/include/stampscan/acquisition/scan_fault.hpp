// What kind of fault ended or troubled a scan, as a value: the panel (and anyone else) maps a kind
// to its advice for the operator instead of searching the error's words. The text stays what it was,
// for the operator and the logs; the kind is what code decides on.
#pragma once

#include <exception>
#include <stdexcept>
#include <string>

#include "stampscan/drivers/plc/modbus_plc.hpp"

namespace stampscan::acquisition {

enum class FaultKind {
  Other,          // a fault with no advice of its own (a plan the cell cannot run, a bad calibration)
  DoorOpen,       // the cell door is (or was opened) open
  EStop,          // the e-stop chain is broken
  LightCurtain,   // the light curtain is (or was) interrupted
  Interlock,      // the PLC's interlock tripped (its heartbeat watchdog, a guard the station does not see)
  NoAir,          // no air pressure: the clamp cannot hold the part
  NotClamped,     // the clamp did not report the part held in time
  StopRequested,  // stopped on request: the operator (panel, Ctrl-C), SIGTERM, the line's PLC
  DeviceSilent,   // a device does not answer (timeout, disconnected, its control lost)
  DataLost,       // measured data is missing (profiles lost, stereo views missing)
};
// Stable snake_case words ("door_open", ...), as the panel's events carry them.
const char* toString(FaultKind kind);

// An error that knows its kind. ScanError (refused before motion) and the jobs' ScanStopped are
// ones; a driver's DeviceError is classified by its code (faultKindOf below).
class FaultError : public std::runtime_error {
 public:
  FaultError(FaultKind kind, const std::string& text) : std::runtime_error(text), kind_(kind) {}
  FaultKind kind() const { return kind_; }

 private:
  FaultKind kind_;
};

// The kind of a PLC event that stops a scan (Other for those that do not); a trip of the PLC's
// interlock by the most pressing cause its fault word names (the e-stop chain, the door, the light
// curtain, the air), so that it gets that cause's advice whichever register the driver read first.
FaultKind faultKindOf(const drivers::plc::PlcEvent& event);
FaultKind faultKindOf(drivers::plc::PlcEventKind kind);
// The kind of any error a scan may end with: a FaultError's own, a DeviceError's from its code,
// Other for the rest.
FaultKind faultKindOf(const std::exception& error);

}  // namespace stampscan::acquisition
