#include "plc_logic.hpp"

namespace stampscan::sim::detail {

using namespace drivers::plc;

modbus_mapping_t* RegisterImage::allocate(const RegisterMap& map) {
  const AddressSpan coils = map.span(RegisterKind::Coil), inputs = map.span(RegisterKind::DiscreteInput),
                    holding = map.span(RegisterKind::HoldingRegister), input_registers = map.span(RegisterKind::InputRegister);
  // libmodbus zeroes the tables and answers an address outside them with exception 0x02.
  return modbus_mapping_new_start_address(coils.first, coils.count, inputs.first, inputs.count, holding.first,
                                          holding.count, input_registers.first, input_registers.count);
}

PlcLogic::PlcLogic(RegisterImage image, const VirtualPlcOptions& options, Clock::time_point now)
    : image_(image), last_heartbeat_change_(now) {
  for (std::uint16_t c = 0; c < kCoilCount; ++c) image_.at(static_cast<Coil>(c)) = 0;
  image_.at(DiscreteInput::DoorClosed) = 1;
  image_.at(DiscreteInput::EStopChainOk) = 1;
  image_.at(DiscreteInput::LightCurtainClear) = 1;
  image_.at(DiscreteInput::PartClamped) = 0;
  image_.at(DiscreteInput::LaserShutterClosed) = 1;
  image_.at(DiscreteInput::AirPressureOk) = 1;
  image_.at(HoldingRegister::StationHeartbeat) = 0;
  image_.at(HoldingRegister::WatchdogTimeoutMs) = options.watchdog_timeout_ms;
  for (std::uint16_t r = 0; r < kInputRegisterCount; ++r) image_.at(static_cast<InputRegister>(r)) = 0;
  image_.at(InputRegister::FirmwareMajor) = options.firmware_major;
  image_.at(InputRegister::FirmwareMinor) = options.firmware_minor;
  evaluate(now);
}

void PlcLogic::cycle(Clock::time_point now) {
  std::uint16_t& counter = image_.at(InputRegister::PlcHeartbeat);
  counter = static_cast<std::uint16_t>(counter + 1U);
  evaluate(now);
}

void PlcLogic::evaluate(Clock::time_point now) {
  RegisterImage& io = image_;

  // Station heartbeat watchdog: a change of value is a beat, whatever the value.
  const std::uint16_t beat = io.at(HoldingRegister::StationHeartbeat);
  if (beat != last_station_heartbeat_) {
    last_station_heartbeat_ = beat;
    last_heartbeat_change_ = now;
    heartbeat_armed_ = true;
    ++heartbeat_changes_;
  }
  io.at(InputRegister::StationHeartbeatEcho) = last_station_heartbeat_;
  const std::uint16_t timeout_ms = io.at(HoldingRegister::WatchdogTimeoutMs);
  const bool heartbeat_lost = heartbeat_armed_ && timeout_ms != 0 &&
                              now - last_heartbeat_change_ > std::chrono::milliseconds(timeout_ms);

  // The clamp actuator moves when the request changes; in between, setInput() may override what
  // the sensor says (a slipped part).
  const bool clamp_request = io.at(Coil::ClampRequest) != 0;
  if (clamp_request != last_clamp_request_) {
    last_clamp_request_ = clamp_request;
    io.at(DiscreteInput::PartClamped) = clamp_request ? 1 : 0;
  }

  std::uint16_t faults = 0;
  const auto raise = [&](bool condition, FaultBit bit) {
    if (condition) faults = static_cast<std::uint16_t>(faults | mask(bit));
  };
  raise(io.at(DiscreteInput::DoorClosed) == 0, FaultBit::DoorOpen);
  raise(io.at(DiscreteInput::EStopChainOk) == 0, FaultBit::EStopBroken);
  raise(io.at(DiscreteInput::LightCurtainClear) == 0, FaultBit::LightCurtainInterrupted);
  raise(heartbeat_lost, FaultBit::StationHeartbeatLost);
  raise(io.at(DiscreteInput::AirPressureOk) == 0, FaultBit::AirPressureLow);

  const bool tripped = tripsInterlock(faults);
  if (tripped) {
    // Forcing the coils themselves (not just the physical outputs) is what makes the restart
    // explicit: the station must ask again once the cause is gone.
    io.at(Coil::LaserShutterOpenRequest) = 0;
    io.at(Coil::MotionEnable) = 0;
  }
  // The shutter's own feedback: it follows the (possibly forced) request.
  io.at(DiscreteInput::LaserShutterClosed) = io.at(Coil::LaserShutterOpenRequest) != 0 ? 0 : 1;
  io.at(InputRegister::FaultWord) = faults;
  io.at(InputRegister::InterlockState) =
      static_cast<std::uint16_t>(tripped ? InterlockState::Tripped : InterlockState::Clear);
}

}  // namespace stampscan::sim::detail
