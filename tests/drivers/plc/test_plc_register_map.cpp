// The register map: consistent in itself, and the same as the table in drivers/plc/REGISTER_MAP.md.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "stampscan/drivers/plc/plc_register_map.hpp"

namespace stampscan::drivers::plc {
namespace {

using Row = std::vector<std::string>;

std::string trim(const std::string& text) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(" \t") - first + 1);
}

// Every Markdown table row ("| a | b |") of the text, split into trimmed cells; an empty row where a
// table ends.
std::vector<Row> tableRows(std::istream& in) {
  std::vector<Row> rows;
  std::string line;
  while (std::getline(in, line)) {
    line = trim(line);
    if (line.size() < 2 || line.front() != '|' || line.back() != '|') {
      if (!rows.empty() && !rows.back().empty()) rows.emplace_back();  // a table ends here
      continue;
    }
    Row cells;
    std::stringstream cells_text(line.substr(1, line.size() - 2));
    std::string cell;
    while (std::getline(cells_text, cell, '|')) cells.push_back(trim(cell));
    rows.push_back(cells);
  }
  return rows;
}

// The rows of the table whose header row is `header`, without the header and the --- row.
std::vector<Row> tableAfter(const std::vector<Row>& rows, const Row& header) {
  std::vector<Row> table;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i] != header) continue;
    for (std::size_t j = i + 2; j < rows.size() && rows[j].size() == header.size(); ++j)
      table.push_back(rows[j]);
    break;
  }
  return table;
}

// "4" for a one-register signal, "4-19" for a wider one: the document's address column.
std::string addressText(const RegisterInfo& reg) {
  std::string text = std::to_string(reg.standard_address);
  if (reg.width > 1) text += "-" + std::to_string(reg.standard_address + reg.width - 1);
  return text;
}

TEST(PlcRegisterMap, StandardAddressesAreUniqueAndContiguousPerKind) {
  std::map<RegisterKind, std::set<int>> addresses;
  std::set<std::string_view> names;
  for (const RegisterInfo& reg : registerTable()) {
    for (int a = reg.standard_address; a < reg.standard_address + reg.width; ++a)
      EXPECT_TRUE(addresses[reg.kind].insert(a).second) << reg.name << " overlaps another " << toString(reg.kind) << " at " << a;
    EXPECT_TRUE(names.insert(reg.name).second) << "two registers named " << reg.name;
    EXPECT_FALSE(reg.meaning.empty()) << reg.name;
    EXPECT_EQ(reg.meaning.find('|'), std::string_view::npos) << reg.name << " would break the table";
  }
  for (const RegisterKind kind : kRegisterKinds) {
    // Numbered from 0 without gaps, so one request reads a whole kind.
    ASSERT_FALSE(addresses[kind].empty()) << toString(kind);
    EXPECT_EQ(*addresses[kind].begin(), 0) << toString(kind);
    EXPECT_EQ(*addresses[kind].rbegin(), static_cast<int>(addresses[kind].size()) - 1) << toString(kind);
    EXPECT_EQ(RegisterMap{}.span(kind).count, addresses[kind].size()) << toString(kind);
  }
  std::set<int> bits;
  for (const FaultBitInfo& bit : faultBits()) EXPECT_TRUE(bits.insert(bit.bit).second) << bit.name;
  EXPECT_EQ(bits.size(), kFaultBitCount);
}

TEST(PlcRegisterMap, AWideSignalKeepsItsRegistersToItself) {
  // line_part_id takes 16 registers: a map that puts another holding register inside them, or runs
  // it off the address space, is refused naming both.
  RegisterMap map;
  map.setAddress(HoldingRegister::CellBusy, static_cast<std::uint16_t>(map.address(HoldingRegister::LinePartId) + 5));
  EXPECT_NE(map.problem().find("cell_busy"), std::string::npos) << map.problem();
  EXPECT_NE(map.problem().find("line_part_id"), std::string::npos) << map.problem();
  RegisterMap off_the_end;
  off_the_end.setAddress(HoldingRegister::LinePartId, 65530);
  EXPECT_NE(off_the_end.problem().find("runs past address 65535"), std::string::npos) << off_the_end.problem();
  RegisterMap moved;  // the whole block elsewhere: fine, and its span counts every register
  moved.setAddress(HoldingRegister::LinePartId, 40);
  EXPECT_EQ(moved.problem(), "");
  EXPECT_EQ(moved.span(RegisterKind::HoldingRegister).count, 40 + kPartIdRegisters);
}

TEST(PlcRegisterMap, PartIdsGoIntoRegistersTwoCharactersEachAndBack) {
  const auto regs = encodePartId("AB-7");
  EXPECT_EQ(regs[0], 0x4142);  // 'A' in the high byte
  EXPECT_EQ(regs[1], 0x2D37);
  EXPECT_EQ(regs[2], 0);
  EXPECT_EQ(decodePartId(regs), "AB-7");
  const std::string longest(kPartIdMaxLength, 'x');
  EXPECT_EQ(decodePartId(encodePartId(longest)), longest);
  EXPECT_EQ(decodePartId(encodePartId("odd")), "odd");
  EXPECT_THROW(encodePartId(longest + "x"), std::invalid_argument);
  EXPECT_THROW(encodePartId("tab\there"), std::invalid_argument);
  auto padded = encodePartId("P1  ");  // a PLC that pads with spaces
  EXPECT_EQ(decodePartId(padded), "P1");
  padded[0] = 0x8041;  // a byte outside ASCII
  EXPECT_EQ(decodePartId(padded), std::nullopt);
  EXPECT_EQ(decodePartId(encodePartId("")), "");
}

TEST(PlcRegisterMap, VerdictAndErrorCodesAreNamedOnce) {
  EXPECT_EQ(describe(LineVerdict::Good).name, "good");
  EXPECT_EQ(describe(LineVerdict::Error).value, 4);
  EXPECT_EQ(describe(LineError::Busy).name, "busy");
  EXPECT_EQ(describe(LineError::Incomplete).value, 7);
  EXPECT_EQ(lineVerdicts().size(), kLineVerdictCount);
  EXPECT_EQ(lineErrors().size(), kLineErrorCount);
}

TEST(PlcRegisterMap, EnumsNameTheirRows) {
  EXPECT_EQ(describe(DiscreteInput::DoorClosed).name, "door_closed");
  EXPECT_EQ(describe(DiscreteInput::AirPressureOk).name, "air_pressure_ok");
  EXPECT_EQ(describe(Coil::MotionEnable).name, "motion_enable");
  EXPECT_EQ(describe(Coil::LaserShutterOpenRequest).kind, RegisterKind::Coil);
  EXPECT_EQ(describe(HoldingRegister::WatchdogTimeoutMs).unit, "ms");
  EXPECT_EQ(describe(InputRegister::InterlockState).name, "interlock_state");
  EXPECT_EQ(describe(FaultBit::StationHeartbeatLost).name, "station_heartbeat_lost");
}

TEST(PlcRegisterMap, InterlockRuleAndFaultWordText) {
  EXPECT_TRUE(tripsInterlock(mask(FaultBit::DoorOpen)));
  EXPECT_TRUE(tripsInterlock(mask(FaultBit::EStopBroken)));
  EXPECT_TRUE(tripsInterlock(mask(FaultBit::LightCurtainInterrupted)));
  EXPECT_TRUE(tripsInterlock(mask(FaultBit::StationHeartbeatLost)));
  EXPECT_FALSE(tripsInterlock(mask(FaultBit::AirPressureLow)));
  EXPECT_FALSE(tripsInterlock(0));
  EXPECT_EQ(describeFaultWord(0), "none");
  EXPECT_EQ(describeFaultWord(mask(FaultBit::DoorOpen) | mask(FaultBit::AirPressureLow)),
            "door_open, air_pressure_low");
  EXPECT_EQ(describeFaultWord(0x8000), "unknown bits 0x8000");
}

TEST(PlcRegisterMap, DocumentHasTheSameTables) {
  std::ifstream file(STAMPSCAN_PLC_REGISTER_MAP_MD);
  ASSERT_TRUE(file) << "cannot open " << STAMPSCAN_PLC_REGISTER_MAP_MD;
  const std::vector<Row> rows = tableRows(file);

  const std::vector<Row> registers = tableAfter(rows, {"name", "kind", "address", "unit", "meaning"});
  ASSERT_EQ(registers.size(), registerTable().size()) << "register rows in the document";
  for (std::size_t i = 0; i < registers.size(); ++i) {
    const RegisterInfo& reg = registerTable()[i];
    const Row expected{std::string(reg.name), toString(reg.kind), addressText(reg), std::string(reg.unit),
                       std::string(reg.meaning)};
    EXPECT_EQ(registers[i], expected) << "document row " << i + 1 << " differs from the code";
  }

  const std::vector<Row> bits = tableAfter(rows, {"fault bit", "name", "meaning"});
  ASSERT_EQ(bits.size(), faultBits().size()) << "fault-bit rows in the document";
  for (std::size_t i = 0; i < bits.size(); ++i) {
    const FaultBitInfo& bit = faultBits()[i];
    const Row expected{std::to_string(bit.bit), std::string(bit.name), std::string(bit.meaning)};
    EXPECT_EQ(bits[i], expected) << "fault bit row " << i + 1 << " differs from the code";
  }

  for (const auto& [header, codes] : {std::pair{"cell_verdict", lineVerdicts()}, std::pair{"cell_error_code", lineErrors()}}) {
    const std::vector<Row> table = tableAfter(rows, {header, "name", "meaning"});
    ASSERT_EQ(table.size(), codes.size()) << header << " rows in the document";
    for (std::size_t i = 0; i < table.size(); ++i)
      EXPECT_EQ(table[i], (Row{std::to_string(codes[i].value), std::string(codes[i].name), std::string(codes[i].meaning)}))
          << header << " row " << i + 1;
  }
}

TEST(PlcRegisterMap, PrintedTablesAreTheDocumentsTables) {
  // registerMapMarkdown() is how the document's tables were made; its text appears verbatim.
  std::ifstream file(STAMPSCAN_PLC_REGISTER_MAP_MD);
  ASSERT_TRUE(file);
  const std::string document((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const std::string printed = registerMapMarkdown();
  // The tables, separated by empty lines: registers, fault bits, the line's verdicts and errors.
  std::vector<std::string> tables;
  for (std::size_t start = 0; start < printed.size();) {
    const std::size_t split = printed.find("\n\n", start);
    const std::size_t end = split == std::string::npos ? printed.size() : split + 1;
    tables.push_back(printed.substr(start, end - start));
    start = end + 1;
  }
  ASSERT_EQ(tables.size(), 4u);
  for (const std::string& table : tables)
    EXPECT_NE(document.find(table), std::string::npos)
        << "regenerate this table of REGISTER_MAP.md from registerMapMarkdown():\n"
        << table;
}

}  // namespace
}  // namespace stampscan::drivers::plc
