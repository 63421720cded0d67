#include "stampscan/drivers/plc/plc_register_map.hpp"

#include <array>
#include <stdexcept>

namespace stampscan::drivers::plc {
namespace {

constexpr std::array<FaultBitInfo, kFaultBitCount> kFaultBits{{
    {"door_open", 0, "the cell door is open; trips the interlock"},
    {"e_stop_broken", 1, "the emergency-stop chain is open; trips the interlock"},
    {"light_curtain_interrupted", 2, "something is in the light curtain; trips the interlock"},
    {"station_heartbeat_lost", 3, "the station heartbeat did not change within the watchdog timeout; trips the interlock"},
    {"air_pressure_low", 4, "the clamp's air supply is low; reported only, does not trip"},
}};

constexpr std::array<CodeInfo, kLineVerdictCount> kLineVerdicts{{
    {0, "none", "no answer yet, or the scan runs"},
    {1, "good", "the part passes: every element is below the forming-limit curve's safety margin"},
    {2, "marginal", "the part is within the safety margin of the forming-limit curve"},
    {3, "failed", "the part is beyond the forming-limit curve, or thinned too much"},
    {4, "error", "no verdict: cell_error_code says why"},
}};

constexpr std::array<CodeInfo, kLineErrorCount> kLineErrors{{
    {0, "none", "no error"},
    {1, "unknown_program", "no part program of the cell has line_program_number as its line number"},
    {2, "busy", "another job runs (a person's scan, a verification or a calibration): request again when cell_ready is 1"},
    {3, "bad_part_id", "line_part_id is empty or holds a character outside printable ASCII"},
    {4, "not_ready", "the cell refused to start (an interlock, the calibration, a device): nothing moved"},
    {5, "aborted", "the scan was stopped: a safety trip, Abort on the panel, or the request dropped while busy"},
    {6, "scan_failed", "the scan ended without a verdict: a device fault, or its report failed"},
    {7, "incomplete", "the scan lacks data its plan asked for: no verdict is given on it"},
}};

template <std::size_t N>
constexpr bool codesMatchEnum(const std::array<CodeInfo, N>& codes) {
  for (std::size_t value = 0; value < N; ++value)
    if (codes[value].value != value) return false;
  return true;
}
static_assert(codesMatchEnum(kLineVerdicts) && codesMatchEnum(kLineErrors), "code tables out of step with the enums");

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

std::span<const CodeInfo> lineVerdicts() { return kLineVerdicts; }
std::span<const CodeInfo> lineErrors() { return kLineErrors; }
const CodeInfo& describe(LineVerdict verdict) { return kLineVerdicts.at(static_cast<std::size_t>(verdict)); }
const CodeInfo& describe(LineError error) { return kLineErrors.at(static_cast<std::size_t>(error)); }

std::array<std::uint16_t, kPartIdRegisters> encodePartId(std::string_view part_id) {
  if (part_id.size() > kPartIdMaxLength)
    throw std::invalid_argument("a part id for the line holds at most " + std::to_string(kPartIdMaxLength) +
                                " characters, not " + std::to_string(part_id.size()));
  std::array<std::uint16_t, kPartIdRegisters> registers{};
  for (std::size_t i = 0; i < part_id.size(); ++i) {
    const auto c = static_cast<unsigned char>(part_id[i]);
    if (c < 0x20 || c > 0x7E)
      throw std::invalid_argument("a part id for the line holds printable ASCII only (character " +
                                  std::to_string(i + 1) + " is not)");
    registers[i / 2] = static_cast<std::uint16_t>(registers[i / 2] | (i % 2 == 0 ? c << 8 : c));
  }
  return registers;
}

std::optional<std::string> decodePartId(std::span<const std::uint16_t, kPartIdRegisters> registers) {
  std::string id;
  for (std::size_t i = 0; i < kPartIdMaxLength; ++i) {
    const unsigned c = i % 2 == 0 ? registers[i / 2] >> 8 : registers[i / 2] & 0xFFU;
    if (c == 0) break;
    if (c < 0x20 || c > 0x7E) return std::nullopt;
    id += static_cast<char>(c);
  }
  while (!id.empty() && id.back() == ' ') id.pop_back();
  return id;
}

std::string registerMapMarkdown() {
  std::string out;
  appendRow(out, {"name", "kind", "address", "unit", "meaning"});
  appendRow(out, {"---", "---", "---", "---", "---"});
  for (const RegisterInfo& reg : registerTable()) {
    std::string address = std::to_string(reg.standard_address);
    if (reg.width > 1) {
      address += '-';
      address += std::to_string(reg.standard_address + reg.width - 1);
    }
    appendRow(out, {reg.name, toString(reg.kind), address, reg.unit, reg.meaning});
  }
  out += '\n';
  appendRow(out, {"fault bit", "name", "meaning"});
  appendRow(out, {"---", "---", "---"});
  for (const FaultBitInfo& bit : kFaultBits)
    appendRow(out, {std::to_string(bit.bit), bit.name, bit.meaning});
  for (const auto& [header, codes] : {std::pair{"cell_verdict", lineVerdicts()}, std::pair{"cell_error_code", lineErrors()}}) {
    out += '\n';
    appendRow(out, {header, "name", "meaning"});
    appendRow(out, {"---", "---", "---"});
    for (const CodeInfo& code : codes) appendRow(out, {std::to_string(code.value), code.name, code.meaning});
  }
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
