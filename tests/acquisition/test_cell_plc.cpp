// A cell whose PLC program puts its signals elsewhere (station/cells/virtual-indexing.toml moves
// every one): its virtual twin serves the file's register map and unit id, and the Cell's driver,
// built from the same file and otherwise unchanged, reads the interlocks and writes the coils there.
#include "stampscan/acquisition/cell.hpp"
#include "stampscan/sim/virtual_cell.hpp"

#include <gtest/gtest.h>

#include <filesystem>

namespace stampscan::acquisition {
namespace {

using drivers::plc::Coil;
using drivers::plc::DiscreteInput;

TEST(CellPlc, TheDriverWorksUnchangedOnAVirtualCellWithTheFilesRegisterMap) {
  CellConfig config = loadCellConfig(std::filesystem::path(STAMPSCAN_CELLS_DIR) / "virtual-indexing.toml");
  ASSERT_NE(config.plc_registers, drivers::plc::RegisterMap::standard());
  sim::VirtualCellOptions twin;
  twin.world = sim::ScanParams::quick();
  twin.world.setCell(config);
  twin.serve_cmm = false;
  twin.plc_address = config.plc.host;
  twin.plc_port = 0;  // a free port: suites may run in parallel
  twin.plc_unit_id = static_cast<std::uint8_t>(config.plc_unit_id);
  twin.plc_registers = config.plc_registers;
  sim::VirtualCell virtual_cell(twin);
  virtual_cell.start();
  config.plc.port = virtual_cell.plc().port();

  Cell cell(config, CellUse::Check);
  drivers::plc::ModbusPlc& plc = cell.plc();
  plc.connect();
  EXPECT_TRUE(plc.readInputs().door_closed);
  EXPECT_FALSE(plc.readInputs().interlockTripped());
  virtual_cell.plc().openDoor();
  const drivers::plc::PlcInputs open = plc.readInputs();
  EXPECT_FALSE(open.door_closed);
  EXPECT_TRUE(open.e_stop_chain_ok);
  EXPECT_TRUE(open.interlockTripped());
  virtual_cell.plc().closeDoor();
  EXPECT_FALSE(plc.readInputs().interlockTripped());

  plc.setOutput(Coil::ClampRequest, true);
  EXPECT_TRUE(virtual_cell.plc().coil(Coil::ClampRequest));
  EXPECT_FALSE(virtual_cell.plc().coil(Coil::MotionEnable));
  EXPECT_TRUE(plc.readInputs().part_clamped);
  drivers::plc::PlcOutputs out;
  out.stack_light_green = true;
  out.laser_shutter_open_request = true;
  plc.writeOutputs(out);
  EXPECT_TRUE(virtual_cell.plc().coil(Coil::StackLightGreen));
  EXPECT_FALSE(virtual_cell.plc().input(DiscreteInput::LaserShutterClosed));
  EXPECT_EQ(plc.readOutputs(), out);
  plc.disconnect();
  virtual_cell.stop();
}

}  // namespace
}  // namespace stampscan::acquisition
