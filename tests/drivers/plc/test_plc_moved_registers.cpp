// A PLC program that puts its signals at its own addresses: the register map as a value (the
// standard map unchanged, clashes and over-wide spans refused naming the signals), and the driver
// against a virtual PLC serving a moved map, checked with a raw Modbus client at the moved
// addresses.
#include <gtest/gtest.h>

#include <modbus.h>

#include <array>
#include <cerrno>
#include <memory>
#include <stdexcept>
#include <string>

#include "plc_test_support.hpp"

namespace stampscan::plc_test {
namespace {

using drivers::plc::AddressSpan;
using drivers::plc::Coil;
using drivers::plc::DiscreteInput;
using drivers::plc::HoldingRegister;
using drivers::plc::InputRegister;
using drivers::plc::PlcInputs;
using drivers::plc::PlcOutputs;
using drivers::plc::RegisterKind;
using drivers::plc::SignalGroup;
using drivers::plc::RegisterMap;
using drivers::plc::registerTable;

// Every signal elsewhere, in another order within its kind, with gaps: discrete inputs from 100,
// coils from 200 (a gap at 203-204), holding registers at 300 and 310, input registers from 400.
RegisterMap movedMap() {
  RegisterMap map;
  map.setAddress(DiscreteInput::DoorClosed, 105);
  map.setAddress(DiscreteInput::EStopChainOk, 104);
  map.setAddress(DiscreteInput::LightCurtainClear, 103);
  map.setAddress(DiscreteInput::PartClamped, 102);
  map.setAddress(DiscreteInput::LaserShutterClosed, 101);
  map.setAddress(DiscreteInput::AirPressureOk, 100);
  map.setAddress(Coil::StackLightGreen, 207);
  map.setAddress(Coil::StackLightAmber, 206);
  map.setAddress(Coil::StackLightRed, 205);
  map.setAddress(Coil::LaserShutterOpenRequest, 202);
  map.setAddress(Coil::ClampRequest, 201);
  map.setAddress(Coil::MotionEnable, 200);
  map.setAddress(HoldingRegister::StationHeartbeat, 310);
  map.setAddress(HoldingRegister::WatchdogTimeoutMs, 300);
  map.setAddress(InputRegister::PlcHeartbeat, 400);
  map.setAddress(InputRegister::StationHeartbeatEcho, 401);
  map.setAddress(InputRegister::FirmwareMajor, 402);
  map.setAddress(InputRegister::FirmwareMinor, 403);
  map.setAddress(InputRegister::FaultWord, 404);
  map.setAddress(InputRegister::InterlockState, 405);
  return map;
}

TEST(RegisterMapValue, TheDefaultIsTheStandardMapOfTheTable) {
  const RegisterMap standard = RegisterMap::standard();
  EXPECT_EQ(standard, RegisterMap{});
  for (std::size_t row = 0; row < registerTable().size(); ++row)
    EXPECT_EQ(standard.addresses[row], registerTable()[row].standard_address) << registerTable()[row].name;
  EXPECT_EQ(standard.address(Coil::MotionEnable), 5);
  EXPECT_EQ(standard.address(InputRegister::FaultWord), 4);
  EXPECT_EQ(standard.span(RegisterKind::DiscreteInput), (AddressSpan{0, 6}));
  EXPECT_EQ(standard.span(RegisterKind::HoldingRegister, SignalGroup::Cell), (AddressSpan{0, 2}));
  EXPECT_EQ(standard.span(RegisterKind::HoldingRegister, SignalGroup::Line), (AddressSpan{2, 23}));
  EXPECT_EQ(standard.span(RegisterKind::HoldingRegister), (AddressSpan{0, 25}));
  EXPECT_EQ(standard.problem(), "");
}

TEST(RegisterMapValue, SpansCoverTheMovedAddresses) {
  const RegisterMap map = movedMap();
  EXPECT_EQ(map.problem(), "");
  EXPECT_EQ(map.span(RegisterKind::DiscreteInput), (AddressSpan{100, 6}));
  EXPECT_EQ(map.span(RegisterKind::Coil), (AddressSpan{200, 8}));
  EXPECT_EQ(map.span(RegisterKind::HoldingRegister, SignalGroup::Cell), (AddressSpan{300, 11}));
  // The line's handshake left where the standard map has it: its own group, its own request.
  EXPECT_EQ(map.span(RegisterKind::HoldingRegister, SignalGroup::Line), (AddressSpan{2, 23}));
  EXPECT_EQ(map.span(RegisterKind::InputRegister), (AddressSpan{400, 6}));
  EXPECT_NE(map, RegisterMap::standard());
}

TEST(RegisterMapValue, TwoSignalsOfOneKindAtOneAddressAreRefusedNamingBoth) {
  RegisterMap map;
  map.setAddress(DiscreteInput::PartClamped, 0);  // door_closed's
  EXPECT_EQ(map.problem(), "door_closed and part_clamped are both discrete-input 0");
  // Kinds are separate address spaces: a coil and a discrete input may share a number.
  RegisterMap shared;
  shared.setAddress(Coil::StackLightGreen, 40);
  shared.setAddress(DiscreteInput::DoorClosed, 40);
  shared.setAddress(HoldingRegister::StationHeartbeat, 40);
  EXPECT_EQ(shared.problem(), "");
  shared.setAddress(Coil::ClampRequest, 40);
  EXPECT_EQ(shared.problem(), "stack_light_green and clamp_request are both coil 40");
}

TEST(RegisterMapValue, AKindSpreadWiderThanOneRequestIsRefused) {
  RegisterMap map;
  map.setAddress(InputRegister::InterlockState, 100);  // 0..100: 101 addresses
  EXPECT_EQ(map.problem(),
            "input-register addresses from plc_heartbeat (0) to interlock_state (100) span 101, more than the 100 "
            "one request reads");
  map.setAddress(InputRegister::InterlockState, 99);
  EXPECT_EQ(map.problem(), "");
}

TEST(RegisterMapValue, TheDriverAndTheVirtualPlcRefuseAMapThatCannotServe) {
  RegisterMap clash;
  clash.setAddress(Coil::MotionEnable, 0);
  ModbusPlcOptions options;
  options.registers = clash;
  try {
    ModbusPlc plc(options);
    ADD_FAILURE() << "a clashing map was accepted by the driver";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("register map: stack_light_green and motion_enable are both coil 0"),
              std::string::npos)
        << e.what();
  }
  sim::VirtualPlcOptions served = virtualPlcOptions();
  served.registers = clash;
  EXPECT_THROW(VirtualPlc{served}, std::invalid_argument);
}

// A raw Modbus TCP client (libmodbus), to look at the wire's addresses without the driver.
class RawClient {
 public:
  explicit RawClient(int port) : context_(modbus_new_tcp("127.0.0.1", port), &modbus_free) {
    if (!context_ || modbus_connect(context_.get()) != 0)
      throw std::runtime_error(std::string("raw Modbus client: ") + modbus_strerror(errno));
  }
  ~RawClient() { modbus_close(context_.get()); }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;

  // The coil at `address`, or -1 when the PLC refuses the request.
  int coil(int address) {
    std::uint8_t bit = 0;
    return modbus_read_bits(context_.get(), address, 1, &bit) == 1 ? bit : -1;
  }
  bool writeCoil(int address, bool on) { return modbus_write_bit(context_.get(), address, on ? 1 : 0) == 1; }
  int inputBit(int address) {
    std::uint8_t bit = 0;
    return modbus_read_input_bits(context_.get(), address, 1, &bit) == 1 ? bit : -1;
  }
  long holding(int address) {
    std::uint16_t value = 0;
    return modbus_read_registers(context_.get(), address, 1, &value) == 1 ? value : -1;
  }
  bool writeHolding(int address, std::uint16_t value) {
    return modbus_write_register(context_.get(), address, value) == 1;
  }
  long inputRegister(int address) {
    std::uint16_t value = 0;
    return modbus_read_input_registers(context_.get(), address, 1, &value) == 1 ? value : -1;
  }

 private:
  std::unique_ptr<modbus_t, void (*)(modbus_t*)> context_;
};

class MovedRegistersTest : public ::testing::Test {
 protected:
  static sim::VirtualPlcOptions served() {
    sim::VirtualPlcOptions options = virtualPlcOptions();
    options.registers = movedMap();
    options.firmware_major = 7;
    options.firmware_minor = 3;
    return options;
  }
  void SetUp() override { plc_.start(); }
  ModbusPlcOptions options() const {
    ModbusPlcOptions options = driverOptions(plc_.port());
    options.registers = movedMap();
    return options;
  }

  VirtualPlc plc_{served()};
};

TEST_F(MovedRegistersTest, TheLinesHandshakeIsReadAndAnsweredAtItsMappedAddresses) {
  // The line's handshake is its own group: here far from the cell's holding registers, and the
  // answer's registers in another order with a gap, each written where the map says.
  RegisterMap map = movedMap();
  map.setAddress(HoldingRegister::LineStartRequest, 520);
  map.setAddress(HoldingRegister::LineProgramNumber, 521);
  map.setAddress(HoldingRegister::LinePartId, 500);
  map.setAddress(HoldingRegister::CellReady, 530);
  map.setAddress(HoldingRegister::CellBusy, 529);
  map.setAddress(HoldingRegister::CellDone, 527);
  map.setAddress(HoldingRegister::CellVerdict, 526);
  map.setAddress(HoldingRegister::CellErrorCode, 525);
  ASSERT_EQ(map.problem(), "");
  sim::VirtualPlcOptions served = virtualPlcOptions();
  served.registers = map;
  VirtualPlc plc(served);
  plc.start();
  ModbusPlcOptions o = driverOptions(plc.port());
  o.registers = map;
  ModbusPlc driver(o);
  driver.connect();
  EXPECT_FALSE(driver.readLineRequest().start);
  plc.requestStart(4711, "coil-07.B");
  const drivers::plc::LineRequest request = driver.readLineRequest();
  EXPECT_TRUE(request.start);
  EXPECT_EQ(request.program_number, 4711);
  EXPECT_EQ(request.part_id, "coil-07.B");
  RawClient raw(plc.port());
  EXPECT_EQ(raw.holding(500), ('c' << 8) | 'o');
  EXPECT_EQ(raw.holding(520), 1);
  EXPECT_EQ(raw.holding(521), 4711);

  const drivers::plc::CellAnswer answer{true, false, true, drivers::plc::LineVerdict::Failed, drivers::plc::LineError::None};
  ASSERT_TRUE(raw.writeHolding(528, 0xBEEF));  // between the answer's registers: never written
  driver.writeCellAnswer(answer);
  EXPECT_EQ(plc.cellAnswer(), answer);
  EXPECT_EQ(driver.readCellAnswer(), answer);
  EXPECT_EQ(raw.holding(530), 1);
  EXPECT_EQ(raw.holding(526), 3);
  EXPECT_EQ(raw.holding(528), 0xBEEF);
  plc.dropStartRequest();
  EXPECT_FALSE(driver.readLineRequest().start);
  driver.disconnect();
}

TEST_F(MovedRegistersTest, TheVirtualPlcServesEachSignalAtItsMappedAddress) {
  RawClient raw(plc_.port());
  EXPECT_EQ(raw.inputRegister(402), 7);  // firmware_major
  EXPECT_EQ(raw.inputRegister(403), 3);
  EXPECT_EQ(raw.holding(300), 1000);     // watchdog_timeout_ms
  EXPECT_EQ(raw.inputBit(105), 1);       // door_closed
  plc_.openDoor();
  EXPECT_EQ(raw.inputBit(105), 0);
  EXPECT_EQ(raw.inputBit(104), 1);       // e_stop_chain_ok
  EXPECT_EQ(raw.inputRegister(404), drivers::plc::mask(drivers::plc::FaultBit::DoorOpen));
  EXPECT_EQ(raw.inputRegister(405), 1);  // interlock_state: tripped
  // The standard addresses are outside the image: refused, not silently another signal.
  EXPECT_EQ(raw.inputBit(0), -1);
  EXPECT_EQ(raw.coil(0), -1);
}

TEST_F(MovedRegistersTest, TheDriverReadsTheInterlocksAtTheMappedAddresses) {
  ModbusPlc driver(options());
  driver.connect();
  PlcInputs in = driver.readInputs();
  EXPECT_TRUE(in.door_closed && in.e_stop_chain_ok && in.light_curtain_clear && in.air_pressure_ok);
  EXPECT_FALSE(in.part_clamped);
  EXPECT_TRUE(in.laser_shutter_closed);
  EXPECT_EQ(in.firmware_major, 7);
  EXPECT_EQ(in.firmware_minor, 3);
  EXPECT_FALSE(in.interlockTripped());

  plc_.openDoor();
  plc_.setAirPressureOk(false);
  in = driver.readInputs();
  EXPECT_FALSE(in.door_closed);
  EXPECT_FALSE(in.air_pressure_ok);
  EXPECT_TRUE(in.e_stop_chain_ok);
  EXPECT_TRUE(in.has(drivers::plc::FaultBit::DoorOpen));
  EXPECT_TRUE(in.has(drivers::plc::FaultBit::AirPressureLow));
  EXPECT_TRUE(in.interlockTripped());
  plc_.closeDoor();
  plc_.breakEStopChain();
  in = driver.readInputs();
  EXPECT_TRUE(in.door_closed);
  EXPECT_FALSE(in.e_stop_chain_ok);
  EXPECT_TRUE(in.interlockTripped());
  // The watchdog thread beats at the mapped heartbeat register, and the PLC echoes it.
  ASSERT_TRUE(waitUntil([&] { return plc_.stationHeartbeatChanges() >= 2; }));
  EXPECT_EQ(driver.readInputs().station_heartbeat_echo, plc_.holdingRegister(HoldingRegister::StationHeartbeat));
}

TEST_F(MovedRegistersTest, TheDriverWritesEachCoilAtItsMappedAddressAndNoneBetween) {
  RawClient raw(plc_.port());
  // Addresses 203 and 204 lie between the map's coils: on a real PLC, other signals.
  ASSERT_TRUE(raw.writeCoil(203, true));
  ASSERT_TRUE(raw.writeCoil(204, true));
  ModbusPlc driver(options());
  driver.connect();
  driver.setOutput(Coil::StackLightGreen, true);
  EXPECT_EQ(raw.coil(207), 1);  // stack_light_green
  EXPECT_EQ(raw.coil(206), 0);
  EXPECT_TRUE(plc_.coil(Coil::StackLightGreen));

  PlcOutputs out;
  out.stack_light_red = true;
  out.laser_shutter_open_request = true;
  out.motion_enable = true;
  driver.writeOutputs(out);
  EXPECT_EQ(raw.coil(207), 0);  // stack_light_green, written 0
  EXPECT_EQ(raw.coil(205), 1);  // stack_light_red
  EXPECT_EQ(raw.coil(202), 1);  // laser_shutter_open_request
  EXPECT_EQ(raw.coil(201), 0);  // clamp_request
  EXPECT_EQ(raw.coil(200), 1);  // motion_enable
  EXPECT_EQ(raw.coil(203), 1);  // untouched
  EXPECT_EQ(raw.coil(204), 1);
  EXPECT_EQ(driver.readOutputs(), out);
  EXPECT_EQ(raw.inputBit(101), 0);  // laser_shutter_closed follows the request: open

  // The interlock forces the mapped coils, and the driver reads them back from there.
  plc_.interruptLightCurtain();
  EXPECT_EQ(raw.coil(202), 0);
  EXPECT_EQ(raw.coil(200), 0);
  const PlcOutputs forced = driver.readOutputs();
  EXPECT_FALSE(forced.laser_shutter_open_request);
  EXPECT_FALSE(forced.motion_enable);
  EXPECT_TRUE(forced.stack_light_red);

  driver.setPlcWatchdogTimeout(std::chrono::milliseconds(1500));
  EXPECT_EQ(raw.holding(300), 1500);
}

TEST_F(MovedRegistersTest, ADriverWithTheStandardMapGetsAClearError) {
  ModbusPlcOptions standard = options();
  standard.registers = RegisterMap::standard();
  standard.watchdog = false;
  ModbusPlc driver(standard);
  try {
    driver.connect();  // identifies the PLC: reads its inputs
    ADD_FAILURE() << "the standard addresses were served";
  } catch (const drivers::DeviceError& e) {
    EXPECT_EQ(e.code(), "protocol");
    EXPECT_NE(std::string(e.what()).find("read discrete inputs at address 0: Illegal data address"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace stampscan::plc_test
