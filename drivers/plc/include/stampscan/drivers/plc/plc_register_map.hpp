// The cell PLC's Modbus registers: written once, used by the driver (drivers/plc) and by the virtual
// PLC (sim/virtual_plc) alike. As with GenICam in Aravis, the wire carries raw bits and registers;
// what they mean comes from this one description. drivers/plc/REGISTER_MAP.md is the same content
// for people (registerMapMarkdown() prints the tables; a test checks the two agree).
//
// Words used here:
// - a signal is one named bit or register (door_closed, stack_light_green, ...), one row of the
//   register table, one value of the enums DiscreteInput, Coil, HoldingRegister, InputRegister;
//   most signals are one bit or one register; line_part_id is several registers (its width);
// - the register table (registerTable()) names each signal, its kind, unit and meaning, and its
//   address in the standard map;
// - a register map (RegisterMap) says at which address each signal is. A real cell's PLC program
//   puts its signals where it likes, so the map is a value, read from the cell file's
//   [plc.registers]; the standard map (a default-constructed RegisterMap) is the table's.
//
// Addresses are 0-based Modbus PDU addresses. Each kind is its own address space. In the standard
// map each kind is numbered from 0 without gaps; any map keeps the addresses of one kind (and one
// group: the line's handshake is its own) within kMaxAddressSpan, so that the whole input state is
// still two requests (discrete inputs, input registers) and the line's handshake one.
//
// This header is the whole register map (no library to link): the cell file's reader uses it too.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace stampscan::drivers::plc {

enum class RegisterKind : std::uint8_t {
  DiscreteInput,    // read-only bit, function 02: what the cell's sensors say
  Coil,             // read/write bit, functions 01/05/15: what the station asks for
  HoldingRegister,  // read/write 16-bit, functions 03/06/16: written by the station, or by the line (line_*)
  InputRegister,    // read-only 16-bit, function 04: the PLC's own state
};
inline constexpr std::array<RegisterKind, 4> kRegisterKinds{RegisterKind::DiscreteInput, RegisterKind::Coil,
                                                            RegisterKind::HoldingRegister,
                                                            RegisterKind::InputRegister};
// "discrete-input", "coil", "holding-register", "input-register": the spelling of the document.
constexpr const char* toString(RegisterKind kind) {
  switch (kind) {
    case RegisterKind::DiscreteInput: return "discrete-input";
    case RegisterKind::Coil: return "coil";
    case RegisterKind::HoldingRegister: return "holding-register";
    case RegisterKind::InputRegister: return "input-register";
  }
  return "unknown";
}

// The enum values number the signals of each kind from 0. In the standard map the signals of a kind
// follow each other in enum order from address 0, each after the last register of the one before (only
// there: the driver and the virtual PLC ask a RegisterMap).

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

// The line's handshake (REGISTER_MAP.md, "Started by the line"): the line's PLC writes the line_*
// registers, the station answers in the cell_* ones.
enum class HoldingRegister : std::uint16_t {
  StationHeartbeat = 0,   // the station changes it at least once per watchdog timeout
  WatchdogTimeoutMs = 1,  // ms; 0 turns the PLC's heartbeat watchdog off
  LineStartRequest = 2,   // written by the line: 1 asks the cell to scan, held until cell_done
  LineProgramNumber = 3,  // written by the line: the part program's line number
  LinePartId = 4,         // written by the line: kPartIdRegisters registers, ASCII
  CellReady = 5,          // written by the station: 1 when a start request would be taken
  CellBusy = 6,           // written by the station: 1 while the line's scan runs
  CellDone = 7,           // written by the station: 1 from the answer until the request drops
  CellVerdict = 8,        // written by the station: a LineVerdict
  CellErrorCode = 9,      // written by the station: a LineError
};
inline constexpr std::uint16_t kHoldingRegisterCount = 10;

// line_part_id: two ASCII characters per register, the first in the high byte (the usual order of
// a PLC's STRING in registers); shorter ids are padded with 0 bytes.
inline constexpr std::uint16_t kPartIdRegisters = 16;
inline constexpr std::size_t kPartIdMaxLength = 2 * kPartIdRegisters;

// The verdict the cell answers the line with (cell_verdict).
enum class LineVerdict : std::uint16_t {
  None = 0,      // no answer yet (or busy)
  Good = 1,      // the part passes the forming-limit check
  Marginal = 2,  // within the safety margin of the forming-limit curve
  Failed = 3,    // beyond the forming-limit curve, or thinned too much
  Error = 4,     // no verdict: cell_error_code says why
};
inline constexpr std::uint16_t kLineVerdictCount = 5;

// Why the cell gave no verdict (cell_error_code; 0 with every other verdict).
enum class LineError : std::uint16_t {
  None = 0,
  UnknownProgram = 1,  // no part program of the cell carries line_program_number
  Busy = 2,            // another job (a person's scan, a calibration) runs: request again later
  BadPartId = 3,       // line_part_id is empty or not printable ASCII
  NotReady = 4,        // the cell refused to start: interlock, calibration or a device; nothing moved
  Aborted = 5,         // the scan was stopped: a safety trip, the panel's Abort, or the request dropped
  ScanFailed = 6,      // the scan ended without a verdict: a device fault, or its report failed
  Incomplete = 7,      // the scan lacks data its plan asked for: its verdict is not given
};
inline constexpr std::uint16_t kLineErrorCount = 8;

enum class InputRegister : std::uint16_t {
  PlcHeartbeat = 0,          // counts PLC logic cycles (wraps); proves the PLC program runs
  StationHeartbeatEcho = 1,  // the last station heartbeat the PLC saw
  FirmwareMajor = 2,
  FirmwareMinor = 3,
  FaultWord = 4,       // one bit per FaultBit
  InterlockState = 5,  // an InterlockState value
};
inline constexpr std::uint16_t kInputRegisterCount = 6;

inline constexpr std::size_t kSignalCount =
    kDiscreteInputCount + kCoilCount + kHoldingRegisterCount + kInputRegisterCount;

// Bits of the fault word (bit number = enum value). Bits of one register, not addresses: no map
// moves them.
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

// The signals the station reads or writes in one request belong to one group. The line's handshake
// (line_* and cell_*) is a group of its own: a map may put it far from the cell's own holding
// registers, and a cell whose line does not start it never touches it.
enum class SignalGroup : std::uint8_t { Cell, Line };

struct RegisterInfo {
  std::string_view name;  // snake_case, as in the document and the cell file's [plc.registers]
  RegisterKind kind;
  std::uint16_t standard_address;  // in the standard map: the first of its `width`
  std::string_view unit;  // "bool", "count", "ms", "bits", "enum", "version", "number", "ascii"
  std::string_view meaning;
  std::uint16_t width = 1;  // registers (or bits) from its address on
  SignalGroup group = SignalGroup::Cell;
};

// A table of the values of an enum-valued register (the line's verdict and error codes).
struct CodeInfo {
  std::uint16_t value;
  std::string_view name;
  std::string_view meaning;
};

struct FaultBitInfo {
  std::string_view name;
  std::uint16_t bit;
  std::string_view meaning;
};

namespace detail {
using K = RegisterKind;
// The one description of the signals. Order: kind, then standard address; the document lists the
// same rows.
inline constexpr std::array<RegisterInfo, kSignalCount> kRegisterTable{{
    {"door_closed", K::DiscreteInput, 0, "bool", "1 when the cell door is closed"},
    {"e_stop_chain_ok", K::DiscreteInput, 1, "bool", "1 when the emergency-stop chain is closed (no e-stop pressed)"},
    {"light_curtain_clear", K::DiscreteInput, 2, "bool", "1 when nothing interrupts the light curtain"},
    {"part_clamped", K::DiscreteInput, 3, "bool", "1 when the clamp holds the part"},
    {"laser_shutter_closed", K::DiscreteInput, 4, "bool", "1 when the laser shutter is closed (feedback from the shutter, not the request)"},
    {"air_pressure_ok", K::DiscreteInput, 5, "bool", "1 when the clamp's air supply is above its minimum"},
    {"stack_light_green", K::Coil, 0, "bool", "green stack light: cell ready or scanning"},
    {"stack_light_amber", K::Coil, 1, "bool", "amber stack light: operator action needed"},
    {"stack_light_red", K::Coil, 2, "bool", "red stack light: fault"},
    {"laser_shutter_open_request", K::Coil, 3, "bool", "1 asks the PLC to open the laser shutter; forced to 0 while the interlock is tripped"},
    {"clamp_request", K::Coil, 4, "bool", "1 asks the PLC to clamp the part, 0 to release it"},
    {"motion_enable", K::Coil, 5, "bool", "1 asks the PLC to enable CMM motion; forced to 0 while the interlock is tripped"},
    {"station_heartbeat", K::HoldingRegister, 0, "count", "written by the station; must change at least once per watchdog timeout"},
    {"watchdog_timeout_ms", K::HoldingRegister, 1, "ms", "how long the station heartbeat may stay unchanged before the PLC trips; 0 turns the watchdog off; default 1000"},
    {"line_start_request", K::HoldingRegister, 2, "bool", "written by the line: 1 asks the cell to scan line_program_number as line_part_id; held until cell_done is 1, then set to 0", 1, SignalGroup::Line},
    {"line_program_number", K::HoldingRegister, 3, "number", "written by the line: the line number of the part program to scan (its program.toml's line_number)", 1, SignalGroup::Line},
    {"line_part_id", K::HoldingRegister, 4, "ascii", "written by the line: the part's id, 2 characters per register (first in the high byte), padded with 0", kPartIdRegisters, SignalGroup::Line},
    {"cell_ready", K::HoldingRegister, 20, "bool", "written by the station: 1 when it watches the line, runs no job and would take a start request", 1, SignalGroup::Line},
    {"cell_busy", K::HoldingRegister, 21, "bool", "written by the station: 1 while the scan the line started runs", 1, SignalGroup::Line},
    {"cell_done", K::HoldingRegister, 22, "bool", "written by the station: 1 once cell_verdict and cell_error_code answer the request; 0 again when the request drops", 1, SignalGroup::Line},
    {"cell_verdict", K::HoldingRegister, 23, "enum", "written by the station: the answer to the last request (verdict table below)", 1, SignalGroup::Line},
    {"cell_error_code", K::HoldingRegister, 24, "enum", "written by the station: why the last request has no verdict (error table below); 0 otherwise", 1, SignalGroup::Line},
    {"plc_heartbeat", K::InputRegister, 0, "count", "PLC logic cycles, wrapping at 65535; changes while the PLC program runs"},
    {"station_heartbeat_echo", K::InputRegister, 1, "count", "the last station_heartbeat value the PLC saw"},
    {"firmware_major", K::InputRegister, 2, "version", "PLC program version, major"},
    {"firmware_minor", K::InputRegister, 3, "version", "PLC program version, minor"},
    {"fault_word", K::InputRegister, 4, "bits", "one bit per present fault (table below)"},
    {"interlock_state", K::InputRegister, 5, "enum", "0 clear, 1 tripped (shutter held closed, motion enable held off)"},
}};
}  // namespace detail

// Every signal, in the order of the document: discrete inputs, coils, holding, input registers.
constexpr std::span<const RegisterInfo, kSignalCount> registerTable() { return detail::kRegisterTable; }

// A signal's row in registerTable().
constexpr std::size_t tableRow(DiscreteInput input) { return static_cast<std::size_t>(input); }
constexpr std::size_t tableRow(Coil coil) { return kDiscreteInputCount + static_cast<std::size_t>(coil); }
constexpr std::size_t tableRow(HoldingRegister reg) {
  return kDiscreteInputCount + kCoilCount + static_cast<std::size_t>(reg);
}
constexpr std::size_t tableRow(InputRegister reg) {
  return kDiscreteInputCount + kCoilCount + kHoldingRegisterCount + static_cast<std::size_t>(reg);
}
// The row of the signal named `name` ("door_closed"), if there is one.
constexpr std::optional<std::size_t> findSignal(std::string_view name) {
  for (std::size_t row = 0; row < kSignalCount; ++row)
    if (registerTable()[row].name == name) return row;
  return std::nullopt;
}

constexpr const RegisterInfo& describe(DiscreteInput input) { return registerTable()[tableRow(input)]; }
constexpr const RegisterInfo& describe(Coil coil) { return registerTable()[tableRow(coil)]; }
constexpr const RegisterInfo& describe(HoldingRegister reg) { return registerTable()[tableRow(reg)]; }
constexpr const RegisterInfo& describe(InputRegister reg) { return registerTable()[tableRow(reg)]; }

namespace detail {
// The enums and the table must agree: each kind's rows in enum order, at standard addresses
// 0..count-1. Checked at compile time so that neither can drift.
constexpr bool tableMatchesEnums() {
  const std::array<std::uint16_t, 4> counts{kDiscreteInputCount, kCoilCount, kHoldingRegisterCount,
                                            kInputRegisterCount};
  std::size_t row = 0;
  for (std::size_t k = 0; k < kRegisterKinds.size(); ++k)
    for (std::uint16_t i = 0, address = 0; i < counts[k]; ++i, ++row) {
      if (kRegisterTable[row].kind != kRegisterKinds[k] || kRegisterTable[row].standard_address != address ||
          kRegisterTable[row].width == 0)
        return false;
      address = static_cast<std::uint16_t>(address + kRegisterTable[row].width);
    }
  return row == kSignalCount && tableRow(InputRegister::InterlockState) == kSignalCount - 1 &&
         kRegisterTable[tableRow(HoldingRegister::LinePartId)].width == kPartIdRegisters;
}
static_assert(tableMatchesEnums(), "register table out of step with the enums");
}  // namespace detail

// The addresses of one kind that a map uses lie in [first, first + count): one request reads them.
struct AddressSpan {
  std::uint16_t first = 0;
  std::uint16_t count = 0;
  bool operator==(const AddressSpan&) const = default;
};

// At most this many addresses from the lowest to the highest of one kind and group: the driver
// reads each such span in one request (Modbus reads at most 125 registers or 2000 bits at once).
inline constexpr std::uint16_t kMaxAddressSpan = 100;

// Where each signal is. Default-constructed: the standard map (the table's addresses), the map of
// REGISTER_MAP.md. A value: copy it freely; every method is const and thread-safe except setAddress.
struct RegisterMap {
  // addresses[row]: the address of registerTable()[row].
  std::array<std::uint16_t, kSignalCount> addresses = [] {
    std::array<std::uint16_t, kSignalCount> standard{};
    for (std::size_t row = 0; row < kSignalCount; ++row) standard[row] = registerTable()[row].standard_address;
    return standard;
  }();

  static constexpr RegisterMap standard() { return {}; }

  // Signal: DiscreteInput, Coil, HoldingRegister or InputRegister.
  template <class Signal>
  constexpr std::uint16_t address(Signal signal) const { return addresses[tableRow(signal)]; }
  template <class Signal>
  constexpr void setAddress(Signal signal, std::uint16_t address) { addresses[tableRow(signal)] = address; }

  // The last address registerTable()[row] occupies (its address for a one-register signal); past
  // 65535 when its width runs off the address space (problem() says so).
  constexpr std::uint32_t lastAddress(std::size_t row) const {
    return std::uint32_t{addresses[row]} + registerTable()[row].width - 1;
  }

  // The addresses of `kind` (of one group, when given), lowest to highest.
  constexpr AddressSpan span(RegisterKind kind, std::optional<SignalGroup> group = std::nullopt) const {
    std::optional<std::uint32_t> low, high;
    for (std::size_t row = 0; row < kSignalCount; ++row) {
      if (registerTable()[row].kind != kind || (group && registerTable()[row].group != *group)) continue;
      const std::uint32_t last = lastAddress(row);
      if (!low || addresses[row] < *low) low = addresses[row];
      if (!high || last > *high) high = last;
    }
    if (!low) return {};
    return {static_cast<std::uint16_t>(*low), static_cast<std::uint16_t>(*high - *low + 1)};
  }

  // Why the map cannot serve, naming the signals by their table names; empty when it can. Two
  // signals of one kind at one address ("door_closed and part_clamped are both discrete-input 10"),
  // or one kind's (and group's) addresses spread over more than kMaxAddressSpan.
  std::string problem() const {
    const auto& table = registerTable();
    for (std::size_t a = 0; a < kSignalCount; ++a)
      if (lastAddress(a) > 0xFFFF)
        return std::string(table[a].name) + " at " + std::to_string(addresses[a]) + " runs past address 65535 (it takes " +
               std::to_string(table[a].width) + " registers)";
    for (std::size_t a = 0; a < kSignalCount; ++a)
      for (std::size_t b = a + 1; b < kSignalCount; ++b) {
        if (table[a].kind != table[b].kind || addresses[a] > lastAddress(b) || addresses[b] > lastAddress(a)) continue;
        if (addresses[a] == addresses[b])
          return std::string(table[a].name) + " and " + std::string(table[b].name) + " are both " +
                 toString(table[a].kind) + " " + std::to_string(addresses[a]);
        const std::size_t wide = table[a].width > 1 ? a : b, other = wide == a ? b : a;
        return std::string(table[other].name) + " (" + toString(table[other].kind) + " " +
               std::to_string(addresses[other]) + ") lies within " + std::string(table[wide].name) + " (" +
               std::to_string(addresses[wide]) + " to " + std::to_string(lastAddress(wide)) + ")";
      }
    for (const RegisterKind kind : kRegisterKinds)
      for (const SignalGroup group : {SignalGroup::Cell, SignalGroup::Line}) {
      const AddressSpan s = span(kind, group);
      if (s.count <= kMaxAddressSpan) continue;
      std::string low, high;
      for (std::size_t row = 0; row < kSignalCount; ++row) {
        if (table[row].kind != kind || table[row].group != group) continue;
        if (addresses[row] == s.first) low = table[row].name;
        if (lastAddress(row) == s.first + s.count - 1u) high = table[row].name;
      }
      return std::string(toString(kind)) + " addresses from " + low + " (" + std::to_string(s.first) + ") to " +
             high + " (" + std::to_string(s.first + s.count - 1) + ") span " + std::to_string(s.count) +
             ", more than the " + std::to_string(kMaxAddressSpan) + " one request reads";
      }
    return {};
  }

  bool operator==(const RegisterMap&) const = default;
};

std::span<const FaultBitInfo> faultBits();
const FaultBitInfo& describe(FaultBit bit);

// The line's side of the handshake (line_* registers), as the line's PLC wrote it.
struct LineRequest {
  bool start = false;
  std::uint16_t program_number = 0;
  // Nothing when line_part_id holds a character outside printable ASCII (decodePartId).
  std::optional<std::string> part_id;
  bool operator==(const LineRequest&) const = default;
};

// The cell's answer to the line (cell_* registers).
struct CellAnswer {
  bool ready = false, busy = false, done = false;
  LineVerdict verdict = LineVerdict::None;
  LineError error = LineError::None;
  bool operator==(const CellAnswer&) const = default;
};

// The values of cell_verdict and cell_error_code, numbered by their enums.
std::span<const CodeInfo> lineVerdicts();
std::span<const CodeInfo> lineErrors();
const CodeInfo& describe(LineVerdict verdict);
const CodeInfo& describe(LineError error);

// line_part_id's registers for `part_id` (padded with 0); throws std::invalid_argument when it is
// longer than kPartIdMaxLength or holds a character outside printable ASCII.
std::array<std::uint16_t, kPartIdRegisters> encodePartId(std::string_view part_id);
// The part id the registers hold: up to the first 0 byte, trailing spaces dropped (a PLC may pad
// with spaces). Nothing when a character is outside printable ASCII.
std::optional<std::string> decodePartId(std::span<const std::uint16_t, kPartIdRegisters> registers);

// The register table (standard map), the fault-bit table and the line's verdict and error tables as
// Markdown, exactly as in REGISTER_MAP.md (tables separated by an empty line).
std::string registerMapMarkdown();
// "door_open, e_stop_broken" for a fault word; "none" when it is 0.
std::string describeFaultWord(std::uint16_t fault_word);

}  // namespace stampscan::drivers::plc
