// The virtual PLC's program: the interlock rules of drivers/plc/REGISTER_MAP.md applied to the
// register image that libmodbus serves. Not thread-safe: the caller holds the image's mutex.
#pragma once

#include <chrono>
#include <cstdint>

#include <modbus.h>

#include "stampscan/sim/virtual_plc.hpp"

namespace stampscan::sim::detail {

// libmodbus's register image seen through a register map: each signal's cell. The image holds each
// kind's span of the map (allocate()), so the signal at address a of a kind is at a - start of that
// kind's table; the addresses in a span's gaps are served but mean nothing.
class RegisterImage {
 public:
  using DiscreteInput = drivers::plc::DiscreteInput;
  using Coil = drivers::plc::Coil;
  using HoldingRegister = drivers::plc::HoldingRegister;
  using InputRegister = drivers::plc::InputRegister;

  // A zeroed image covering the map's spans (the caller frees it with modbus_mapping_free); null
  // when it cannot be allocated.
  static modbus_mapping_t* allocate(const drivers::plc::RegisterMap& map);
  // `image` must cover `map` (come from allocate(map)) and outlive this.
  RegisterImage(modbus_mapping_t& image, const drivers::plc::RegisterMap& map) : image_(image), map_(map) {}

  // A view, like std::span: const does not reach the image.
  std::uint8_t& at(DiscreteInput s) const {
    return image_.tab_input_bits[map_.address(s) - image_.start_input_bits];
  }
  std::uint8_t& at(Coil s) const { return image_.tab_bits[map_.address(s) - image_.start_bits]; }
  std::uint16_t& at(HoldingRegister s) const {
    return image_.tab_registers[map_.address(s) - image_.start_registers];
  }
  std::uint16_t& at(InputRegister s) const {
    return image_.tab_input_registers[map_.address(s) - image_.start_input_registers];
  }

 private:
  modbus_mapping_t& image_;
  drivers::plc::RegisterMap map_;
};

class PlcLogic {
 public:
  using Clock = std::chrono::steady_clock;

  // Fills the image with a healthy, idle cell (see VirtualPlc's constructor).
  PlcLogic(RegisterImage image, const VirtualPlcOptions& options, Clock::time_point now);

  // Runs the program once over the image. Called after every change (a client's request, an input
  // set by a test) so that its effects are visible at once, and every cycle for the watchdog.
  void evaluate(Clock::time_point now);
  // One logic cycle: counts plc_heartbeat, then evaluates.
  void cycle(Clock::time_point now);

  std::uint64_t stationHeartbeatChanges() const { return heartbeat_changes_; }
  const RegisterImage& image() const { return image_; }

 private:
  RegisterImage image_;
  std::uint16_t last_station_heartbeat_ = 0;
  Clock::time_point last_heartbeat_change_;
  // The watchdog starts with the first heartbeat: a PLC powered up before the station has nobody
  // to watch yet, and tripping then would only force every start-up through a reset.
  bool heartbeat_armed_ = false;
  bool last_clamp_request_ = false;
  std::uint64_t heartbeat_changes_ = 0;
};

}  // namespace stampscan::sim::detail
