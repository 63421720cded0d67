#include "plc_logic.hpp"

namespace stampscan::sim::detail {

using namespace drivers::plc;

PlcLogic::PlcLogic(modbus_mapping_t& image, const VirtualPlcOptions& options, Clock::time_point now)
    : image_(image), last_heartbeat_change_(now) {
  for (std::uint16_t a = 0; a < kCoilCount; ++a) image_.tab_bits[a] = 0;
  std::uint8_t* in = image_.tab_input_bits;
  in[address(DiscreteInput::DoorClosed)] = 1;
  in[address(DiscreteInput::EStopChainOk)] = 1;
  in[address(DiscreteInput::LightCurtainClear)] = 1;
  in[address(DiscreteInput::PartClamped)] = 0;
  in[address(DiscreteInput::LaserShutterClosed)] = 1;
  in[address(DiscreteInput::AirPressureOk)] = 1;
  image_.tab_registers[address(HoldingRegister::StationHeartbeat)] = 0;
  image_.tab_registers[address(HoldingRegister::WatchdogTimeoutMs)] = options.watchdog_timeout_ms;
  std::uint16_t* ir = image_.tab_input_registers;
  for (std::uint16_t a = 0; a < kInputRegisterCount; ++a) ir[a] = 0;
  ir[address(InputRegister::FirmwareMajor)] = options.firmware_major;
  ir[address(InputRegister::FirmwareMinor)] = options.firmware_minor;
  evaluate(now);
}

void PlcLogic::cycle(Clock::time_point now) {
  std::uint16_t& counter = image_.tab_input_registers[address(InputRegister::PlcHeartbeat)];
  counter = static_cast<std::uint16_t>(counter + 1U);
  evaluate(now);
}

void PlcLogic::evaluate(Clock::time_point now) {
  std::uint8_t* in = image_.tab_input_bits;
  std::uint8_t* coils = image_.tab_bits;
  const std::uint16_t* holding = image_.tab_registers;
  std::uint16_t* ir = image_.tab_input_registers;

  // Station heartbeat watchdog: a change of value is a beat, whatever the value.
  const std::uint16_t beat = holding[address(HoldingRegister::StationHeartbeat)];
  if (beat != last_station_heartbeat_) {
    last_station_heartbeat_ = beat;
    last_heartbeat_change_ = now;
    heartbeat_armed_ = true;
    ++heartbeat_changes_;
  }
  ir[address(InputRegister::StationHeartbeatEcho)] = last_station_heartbeat_;
  const std::uint16_t timeout_ms = holding[address(HoldingRegister::WatchdogTimeoutMs)];
  const bool heartbeat_lost = heartbeat_armed_ && timeout_ms != 0 &&
                              now - last_heartbeat_change_ > std::chrono::milliseconds(timeout_ms);

  // The clamp actuator moves when the request changes; in between, setInput() may override what
  // the sensor says (a slipped part).
  const bool clamp_request = coils[address(Coil::ClampRequest)] != 0;
  if (clamp_request != last_clamp_request_) {
    last_clamp_request_ = clamp_request;
    in[address(DiscreteInput::PartClamped)] = clamp_request ? 1 : 0;
  }

  std::uint16_t faults = 0;
  const auto raise = [&](bool condition, FaultBit bit) {
    if (condition) faults = static_cast<std::uint16_t>(faults | mask(bit));
  };
  raise(in[address(DiscreteInput::DoorClosed)] == 0, FaultBit::DoorOpen);
  raise(in[address(DiscreteInput::EStopChainOk)] == 0, FaultBit::EStopBroken);
  raise(in[address(DiscreteInput::LightCurtainClear)] == 0, FaultBit::LightCurtainInterrupted);
  raise(heartbeat_lost, FaultBit::StationHeartbeatLost);
  raise(in[address(DiscreteInput::AirPressureOk)] == 0, FaultBit::AirPressureLow);

  const bool tripped = tripsInterlock(faults);
  if (tripped) {
    // Forcing the coils themselves (not just the physical outputs) is what makes the restart
    // explicit: the station must ask again once the cause is gone.
    coils[address(Coil::LaserShutterOpenRequest)] = 0;
    coils[address(Coil::MotionEnable)] = 0;
  }
  // The shutter's own feedback: it follows the (possibly forced) request.
  in[address(DiscreteInput::LaserShutterClosed)] =
      coils[address(Coil::LaserShutterOpenRequest)] != 0 ? 0 : 1;
  ir[address(InputRegister::FaultWord)] = faults;
  ir[address(InputRegister::InterlockState)] =
      static_cast<std::uint16_t>(tripped ? InterlockState::Tripped : InterlockState::Clear);
}

}  // namespace stampscan::sim::detail
