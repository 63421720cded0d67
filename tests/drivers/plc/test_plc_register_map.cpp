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

// Every Markdown table row ("| a | b |") of the text, split into trimmed cells.
std::vector<Row> tableRows(std::istream& in) {
  std::vector<Row> rows;
  std::string line;
  while (std::getline(in, line)) {
    line = trim(line);
    if (line.size() < 2 || line.front() != '|' || line.back() != '|') continue;
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

TEST(PlcRegisterMap, StandardAddressesAreUniqueAndContiguousPerKind) {
  std::map<RegisterKind, std::set<int>> addresses;
  std::set<std::string_view> names;
  for (const RegisterInfo& reg : registerTable()) {
    EXPECT_TRUE(addresses[reg.kind].insert(reg.standard_address).second)
        << reg.name << " overlaps another " << toString(reg.kind) << " at " << reg.standard_address;
    EXPECT_TRUE(names.insert(reg.name).second) << "two registers named " << reg.name;
    EXPECT_FALSE(reg.meaning.empty()) << reg.name;
    EXPECT_EQ(reg.meaning.find('|'), std::string_view::npos) << reg.name << " would break the table";
  }
  const std::map<RegisterKind, int> counts{{RegisterKind::DiscreteInput, kDiscreteInputCount},
                                           {RegisterKind::Coil, kCoilCount},
                                           {RegisterKind::HoldingRegister, kHoldingRegisterCount},
                                           {RegisterKind::InputRegister, kInputRegisterCount}};
  for (const auto& [kind, count] : counts) {
    // Numbered 0..count-1 without gaps, so one request reads a whole kind.
    ASSERT_EQ(addresses[kind].size(), static_cast<std::size_t>(count)) << toString(kind);
    EXPECT_EQ(*addresses[kind].begin(), 0) << toString(kind);
    EXPECT_EQ(*addresses[kind].rbegin(), count - 1) << toString(kind);
  }
  std::set<int> bits;
  for (const FaultBitInfo& bit : faultBits()) EXPECT_TRUE(bits.insert(bit.bit).second) << bit.name;
  EXPECT_EQ(bits.size(), kFaultBitCount);
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
    const Row expected{std::string(reg.name), toString(reg.kind), std::to_string(reg.standard_address),
                       std::string(reg.unit), std::string(reg.meaning)};
    EXPECT_EQ(registers[i], expected) << "document row " << i + 1 << " differs from the code";
  }

  const std::vector<Row> bits = tableAfter(rows, {"fault bit", "name", "meaning"});
  ASSERT_EQ(bits.size(), faultBits().size()) << "fault-bit rows in the document";
  for (std::size_t i = 0; i < bits.size(); ++i) {
    const FaultBitInfo& bit = faultBits()[i];
    const Row expected{std::to_string(bit.bit), std::string(bit.name), std::string(bit.meaning)};
    EXPECT_EQ(bits[i], expected) << "fault bit row " << i + 1 << " differs from the code";
  }
}

TEST(PlcRegisterMap, PrintedTablesAreTheDocumentsTables) {
  // registerMapMarkdown() is how the document's tables were made; its text appears verbatim.
  std::ifstream file(STAMPSCAN_PLC_REGISTER_MAP_MD);
  ASSERT_TRUE(file);
  const std::string document((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const std::string printed = registerMapMarkdown();
  const std::size_t split = printed.find("\n\n");  // the register table, then the fault bits
  ASSERT_NE(split, std::string::npos);
  for (const std::string& table : {printed.substr(0, split + 1), printed.substr(split + 2)})
    EXPECT_NE(document.find(table), std::string::npos)
        << "regenerate this table of REGISTER_MAP.md from registerMapMarkdown():\n"
        << table;
}

}  // namespace
}  // namespace stampscan::drivers::plc
