#include "stampscan/acquisition/scan_fault.hpp"

#include "stampscan/drivers/device.hpp"

namespace stampscan::acquisition {

const char* toString(FaultKind kind) {
  switch (kind) {
    case FaultKind::Other: return "other";
    case FaultKind::DoorOpen: return "door_open";
    case FaultKind::EStop: return "e_stop";
    case FaultKind::LightCurtain: return "light_curtain";
    case FaultKind::Interlock: return "interlock";
    case FaultKind::NoAir: return "no_air";
    case FaultKind::NotClamped: return "not_clamped";
    case FaultKind::StopRequested: return "stop_requested";
    case FaultKind::DeviceSilent: return "device_silent";
    case FaultKind::DataLost: return "data_lost";
  }
  return "other";
}

FaultKind faultKindOf(drivers::plc::PlcEventKind kind) {
  using drivers::plc::PlcEventKind;
  switch (kind) {
    case PlcEventKind::DoorOpened: return FaultKind::DoorOpen;
    case PlcEventKind::EStopBroken: return FaultKind::EStop;
    case PlcEventKind::LightCurtainInterrupted: return FaultKind::LightCurtain;
    case PlcEventKind::AirPressureLost: return FaultKind::NoAir;
    case PlcEventKind::InterlockTripped: return FaultKind::Interlock;
    case PlcEventKind::ConnectionLost:
    case PlcEventKind::PlcSilent: return FaultKind::DeviceSilent;
    case PlcEventKind::DoorClosed:
    case PlcEventKind::EStopRestored:
    case PlcEventKind::LightCurtainCleared:
    case PlcEventKind::AirPressureRestored:
    case PlcEventKind::InterlockCleared:
    case PlcEventKind::Reconnected:
    case PlcEventKind::PlcAnswering: return FaultKind::Other;
  }
  return FaultKind::Other;
}

FaultKind faultKindOf(const drivers::plc::PlcEvent& event) {
  using drivers::plc::FaultBit;
  if (event.kind == drivers::plc::PlcEventKind::InterlockTripped) {
    const auto has = [&](FaultBit bit) { return (event.fault_word & (1U << static_cast<unsigned>(bit))) != 0; };
    if (has(FaultBit::EStopBroken)) return FaultKind::EStop;
    if (has(FaultBit::DoorOpen)) return FaultKind::DoorOpen;
    if (has(FaultBit::LightCurtainInterrupted)) return FaultKind::LightCurtain;
    if (has(FaultBit::AirPressureLow)) return FaultKind::NoAir;
  }
  return faultKindOf(event.kind);
}

FaultKind faultKindOf(const std::exception& error) {
  if (const auto* fault = dynamic_cast<const FaultError*>(&error)) return fault->kind();
  if (const auto* device = dynamic_cast<const drivers::DeviceError*>(&error)) {
    // The drivers' codes for "it does not answer" (device.hpp's DeviceFault::code).
    const std::string& code = device->code();
    for (const char* silent : {"timeout", "disconnected", "plc-silent", "not-found", "connect"})
      if (code == silent) return FaultKind::DeviceSilent;
  }
  return FaultKind::Other;
}

}  // namespace stampscan::acquisition
