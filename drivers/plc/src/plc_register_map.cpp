#include "stampscan/drivers/plc/plc_register_map.hpp"

#include <array>

namespace stampscan::drivers::plc {
namespace {

constexpr std::array<FaultBitInfo, kFaultBitCount> kFaultBits{{
    {"door_open", 0, "the cell door is open; trips the interlock"},
    {"e_stop_broken", 1, "the emergency-stop chain is open; trips the interlock"},
    {"light_curtain_interrupted", 2, "something is in the light curtain; trips the interlock"},
    {"station_heartbeat_lost", 3, "the station heartbeat did not change within the watchdog timeout; trips the interlock"},
    {"air_pressure_low", 4, "the clamp's air supply is low; reported only, does not trip"},
}};

// The fault bits are numbered by their enum, without gaps.
constexpr bool bitsMatchEnum() {
  for (std::uint16_t bit = 0; bit < kFaultBitCount; ++bit)
    if (kFaultBits[bit].bit != bit) return false;
  return true;
}
static_assert(bitsMatchEnum(), "fault-bit table out of step with the enum");

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

std::span<const FaultBitInfo> faultBits() { return kFaultBits; }

const FaultBitInfo& describe(FaultBit bit) { return kFaultBits[static_cast<std::size_t>(bit)]; }

std::string registerMapMarkdown() {
  std::string out;
  appendRow(out, {"name", "kind", "address", "unit", "meaning"});
  appendRow(out, {"---", "---", "---", "---", "---"});
  for (const RegisterInfo& reg : registerTable())
    appendRow(out, {reg.name, toString(reg.kind), std::to_string(reg.standard_address), reg.unit, reg.meaning});
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
