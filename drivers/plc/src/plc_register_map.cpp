#include "stampscan/drivers/plc/plc_register_map.hpp"

#include <array>

namespace stampscan::drivers::plc {
namespace {

using K = RegisterKind;

// The one description of the map. Order: kind, then address; the document lists the same rows.
constexpr std::array<RegisterInfo, 20> kRegisters{{
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
    {"plc_heartbeat", K::InputRegister, 0, "count", "PLC logic cycles, wrapping at 65535; changes while the PLC program runs"},
    {"station_heartbeat_echo", K::InputRegister, 1, "count", "the last station_heartbeat value the PLC saw"},
    {"firmware_major", K::InputRegister, 2, "version", "PLC program version, major"},
    {"firmware_minor", K::InputRegister, 3, "version", "PLC program version, minor"},
    {"fault_word", K::InputRegister, 4, "bits", "one bit per present fault (table below)"},
    {"interlock_state", K::InputRegister, 5, "enum", "0 clear, 1 tripped (shutter held closed, motion enable held off)"},
}};

constexpr std::array<FaultBitInfo, kFaultBitCount> kFaultBits{{
    {"door_open", 0, "the cell door is open; trips the interlock"},
    {"e_stop_broken", 1, "the emergency-stop chain is open; trips the interlock"},
    {"light_curtain_interrupted", 2, "something is in the light curtain; trips the interlock"},
    {"station_heartbeat_lost", 3, "the station heartbeat did not change within the watchdog timeout; trips the interlock"},
    {"air_pressure_low", 4, "the clamp's air supply is low; reported only, does not trip"},
}};

constexpr std::size_t firstIndex(RegisterKind kind) {
  std::size_t index = 0;
  while (index < kRegisters.size() && kRegisters[index].kind != kind) ++index;
  return index;
}

// The enums above and the table must agree; checked at compile time so that neither can drift.
constexpr bool tableMatchesEnums() {
  const std::array<std::uint16_t, 4> counts{kDiscreteInputCount, kCoilCount, kHoldingRegisterCount,
                                            kInputRegisterCount};
  const std::array<RegisterKind, 4> kinds{K::DiscreteInput, K::Coil, K::HoldingRegister,
                                          K::InputRegister};
  std::size_t index = 0;
  for (std::size_t k = 0; k < kinds.size(); ++k) {
    for (std::uint16_t a = 0; a < counts[k]; ++a, ++index) {
      if (index >= kRegisters.size() || kRegisters[index].kind != kinds[k] ||
          kRegisters[index].address != a)
        return false;
    }
  }
  for (std::uint16_t bit = 0; bit < kFaultBitCount; ++bit)
    if (kFaultBits[bit].bit != bit) return false;
  return index == kRegisters.size();
}
static_assert(tableMatchesEnums(), "register table out of step with the enums");

const RegisterInfo& at(RegisterKind kind, std::uint16_t address) {
  return kRegisters[firstIndex(kind) + address];
}

void appendRow(std::string& out, std::initializer_list<std::string_view> cells) {
  out += '|';
  for (std::string_view cell : cells) {
    out += ' ';
    out += cell;
    out += " |";
  }
  out += '\n';
}

}  // namespace

const char* toString(RegisterKind kind) {
  switch (kind) {
    case K::DiscreteInput: return "discrete-input";
    case K::Coil: return "coil";
    case K::HoldingRegister: return "holding-register";
    case K::InputRegister: return "input-register";
  }
  return "unknown";
}

std::span<const RegisterInfo> registerMap() { return kRegisters; }
std::span<const FaultBitInfo> faultBits() { return kFaultBits; }

const RegisterInfo& describe(DiscreteInput input) { return at(K::DiscreteInput, address(input)); }
const RegisterInfo& describe(Coil coil) { return at(K::Coil, address(coil)); }
const RegisterInfo& describe(HoldingRegister reg) { return at(K::HoldingRegister, address(reg)); }
const RegisterInfo& describe(InputRegister reg) { return at(K::InputRegister, address(reg)); }
const FaultBitInfo& describe(FaultBit bit) { return kFaultBits[static_cast<std::size_t>(bit)]; }

std::string registerMapMarkdown() {
  std::string out;
  appendRow(out, {"name", "kind", "address", "unit", "meaning"});
  appendRow(out, {"---", "---", "---", "---", "---"});
  for (const RegisterInfo& reg : kRegisters)
    appendRow(out, {reg.name, toString(reg.kind), std::to_string(reg.address), reg.unit, reg.meaning});
  out += '\n';
  appendRow(out, {"fault bit", "name", "meaning"});
  appendRow(out, {"---", "---", "---"});
  for (const FaultBitInfo& bit : kFaultBits)
    appendRow(out, {std::to_string(bit.bit), bit.name, bit.meaning});
  return out;
}

std::string describeFaultWord(std::uint16_t fault_word) {
  std::string out;
  for (const FaultBitInfo& bit : kFaultBits) {
    if ((fault_word & (1U << bit.bit)) == 0) continue;
    if (!out.empty()) out += ", ";
    out += bit.name;
  }
  const unsigned unknown = fault_word & ~((1U << kFaultBitCount) - 1U);
  if (unknown != 0) {
    if (!out.empty()) out += ", ";
    out += "unknown bits 0x" + [unknown] {
      static const char* digits = "0123456789abcdef";
      std::string hex;
      for (int shift = 12; shift >= 0; shift -= 4) hex += digits[(unknown >> shift) & 0xFU];
      return hex;
    }();
  }
  return out.empty() ? "none" : out;
}

}  // namespace stampscan::drivers::plc
