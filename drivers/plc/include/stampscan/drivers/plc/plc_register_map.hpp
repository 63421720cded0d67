// The cell PLC's Modbus register map: written once, used by the driver (drivers/plc) and by the
// virtual PLC (sim/virtual_plc) alike. As with GenICam in Aravis, the wire carries raw bits and
// registers; what they mean comes from this one description. drivers/plc/REGISTER_MAP.md is the same
// content for people (registerMapMarkdown() prints the tables; a test checks the two agree).
//
// Addresses are 0-based Modbus PDU addresses. Each kind is its own address space, numbered from 0
// without gaps, so the whole input state is two requests (discrete inputs, input registers).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace stampscan::drivers::plc {

enum class RegisterKind : std::uint8_t {
  DiscreteInput,    // read-only bit, function 02: what the cell's sensors say
  Coil,             // read/write bit, functions 01/05/15: what the station asks for
  HoldingRegister,  // read/write 16-bit, functions 03/06/16: written by the station
  InputRegister,    // read-only 16-bit, function 04: the PLC's own state
};
// "discrete-input", "coil", "holding-register", "input-register": the spelling of the document.
const char* toString(RegisterKind kind);

// Read-only bits from the cell's sensors. "true" is always the safe or healthy state, so a broken
// wire (reads 0) shows as the unsafe state.
enum class DiscreteInput : std::uint16_t {
  DoorClosed = 0,
  EStopChainOk = 1,
  LightCurtainClear = 2,
  PartClamped = 3,
  LaserShutterClosed = 4,  // feedback from the shutter itself, not the request
  AirPressureOk = 5,
};
inline constexpr std::uint16_t kDiscreteInputCount = 6;

// Outputs the station requests. The PLC forces LaserShutterOpenRequest and MotionEnable to 0 while
// the interlock is tripped; they stay 0 afterwards until the station writes them again.
enum class Coil : std::uint16_t {
  StackLightGreen = 0,
  StackLightAmber = 1,
  StackLightRed = 2,
  LaserShutterOpenRequest = 3,
  ClampRequest = 4,
  MotionEnable = 5,
};
inline constexpr std::uint16_t kCoilCount = 6;

enum class HoldingRegister : std::uint16_t {
  StationHeartbeat = 0,   // the station changes it at least once per watchdog timeout
  WatchdogTimeoutMs = 1,  // ms; 0 turns the PLC's heartbeat watchdog off
};
inline constexpr std::uint16_t kHoldingRegisterCount = 2;

enum class InputRegister : std::uint16_t {
  PlcHeartbeat = 0,          // counts PLC logic cycles (wraps); proves the PLC program runs
  StationHeartbeatEcho = 1,  // the last station heartbeat the PLC saw
  FirmwareMajor = 2,
  FirmwareMinor = 3,
  FaultWord = 4,       // one bit per FaultBit
  InterlockState = 5,  // an InterlockState value
};
inline constexpr std::uint16_t kInputRegisterCount = 6;

// Bits of the fault word (bit number = enum value).
enum class FaultBit : std::uint16_t {
  DoorOpen = 0,
  EStopBroken = 1,
  LightCurtainInterrupted = 2,
  StationHeartbeatLost = 3,
  AirPressureLow = 4,
};
inline constexpr std::uint16_t kFaultBitCount = 5;

enum class InterlockState : std::uint16_t {
  Clear = 0,    // no trip condition: the shutter may open and motion may be enabled on request
  Tripped = 1,  // a trip condition holds: shutter held closed, motion enable held off
};

constexpr std::uint16_t address(DiscreteInput input) { return static_cast<std::uint16_t>(input); }
constexpr std::uint16_t address(Coil coil) { return static_cast<std::uint16_t>(coil); }
constexpr std::uint16_t address(HoldingRegister reg) { return static_cast<std::uint16_t>(reg); }
constexpr std::uint16_t address(InputRegister reg) { return static_cast<std::uint16_t>(reg); }
constexpr std::uint16_t mask(FaultBit bit) {
  return static_cast<std::uint16_t>(1U << static_cast<unsigned>(bit));
}

// The interlock rule, shared by the PLC (which acts on it) and the driver (which reports it): these
// faults close the shutter and drop motion enable. Low air pressure is reported but does not trip.
inline constexpr std::uint16_t kInterlockTripMask =
    mask(FaultBit::DoorOpen) | mask(FaultBit::EStopBroken) |
    mask(FaultBit::LightCurtainInterrupted) | mask(FaultBit::StationHeartbeatLost);
constexpr bool tripsInterlock(std::uint16_t fault_word) {
  return (fault_word & kInterlockTripMask) != 0;
}

inline constexpr std::uint16_t kDefaultWatchdogTimeoutMs = 1000;
inline constexpr int kDefaultTcpPort = 1502;  // the virtual cell's contract (ARCHITECTURE.md)

struct RegisterInfo {
  std::string_view name;  // snake_case, as in the document
  RegisterKind kind;
  std::uint16_t address;
  std::string_view unit;  // "bool", "count", "ms", "bits", "enum", "version"
  std::string_view meaning;
};

struct FaultBitInfo {
  std::string_view name;
  std::uint16_t bit;
  std::string_view meaning;
};

// Every register, in the order of the document: discrete inputs, coils, holding, input registers.
std::span<const RegisterInfo> registerMap();
std::span<const FaultBitInfo> faultBits();
const RegisterInfo& describe(DiscreteInput input);
const RegisterInfo& describe(Coil coil);
const RegisterInfo& describe(HoldingRegister reg);
const RegisterInfo& describe(InputRegister reg);
const FaultBitInfo& describe(FaultBit bit);

// The register table and the fault-bit table as Markdown, exactly as in REGISTER_MAP.md.
std::string registerMapMarkdown();
// "door_open, e_stop_broken" for a fault word; "none" when it is 0.
std::string describeFaultWord(std::uint16_t fault_word);

}  // namespace stampscan::drivers::plc
