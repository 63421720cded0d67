// The ModbusPlc driver against the virtual PLC over Modbus TCP on loopback: identity, inputs,
// outputs, heartbeat, and the interlock seen from the station when a door opens mid-scan.
#include <gtest/gtest.h>

#include "plc_test_support.hpp"

namespace stampscan::plc_test {
namespace {

using drivers::DeviceState;
using drivers::plc::Coil;
using drivers::plc::DiscreteInput;
using drivers::plc::FaultBit;
using drivers::plc::HoldingRegister;
using drivers::plc::InputRegister;
using drivers::plc::PlcInputs;
using drivers::plc::PlcOutputs;

using ModbusPlcTest = PlcFixture;

TEST(ModbusPlcIdentity, FirmwareComesFromTheInputRegisters) {
  sim::VirtualPlcOptions plc_options = virtualPlcOptions();
  plc_options.firmware_major = 2;
  plc_options.firmware_minor = 7;
  VirtualPlc plc(plc_options);
  plc.start();
  ASSERT_NE(plc.port(), 0);
  ModbusPlc driver(driverOptions(plc.port()));
  driver.connect();
  EXPECT_EQ(driver.state(), DeviceState::Ready);
  const drivers::DeviceIdentity id = driver.identity();
  EXPECT_EQ(id.family, "plc");
  EXPECT_EQ(id.firmware, "2.7");
  EXPECT_EQ(id.address, "127.0.0.1:" + std::to_string(plc.port()));
  EXPECT_TRUE(driver.check());
  driver.disconnect();
  EXPECT_EQ(driver.state(), DeviceState::Disconnected);
  EXPECT_THROW(driver.readInputs(), drivers::DeviceError);
}

TEST_F(ModbusPlcTest, ReadsTheWholeInputState) {
  ModbusPlc driver(options());
  driver.connect();
  PlcInputs in = driver.readInputs();
  EXPECT_TRUE(in.door_closed);
  EXPECT_TRUE(in.e_stop_chain_ok);
  EXPECT_TRUE(in.light_curtain_clear);
  EXPECT_FALSE(in.part_clamped);
  EXPECT_TRUE(in.laser_shutter_closed);
  EXPECT_TRUE(in.air_pressure_ok);
  EXPECT_EQ(in.fault_word, 0);
  EXPECT_FALSE(in.interlockTripped());
  EXPECT_EQ(in.firmware_major, 1);

  plc_.setPartClamped(true);
  plc_.setAirPressureOk(false);
  in = driver.readInputs();
  EXPECT_TRUE(in.part_clamped);
  EXPECT_FALSE(in.air_pressure_ok);
  EXPECT_TRUE(in.has(FaultBit::AirPressureLow));
  EXPECT_FALSE(in.interlockTripped()) << "low air is reported, it does not trip";
  EXPECT_FALSE(driver.check()) << "the health check reports the PLC's fault";
}

TEST_F(ModbusPlcTest, WritesOutputsAndReadsThemBack) {
  ModbusPlc driver(options());
  driver.connect();
  PlcOutputs out;
  out.stack_light_green = true;
  out.stack_light_red = true;
  out.laser_shutter_open_request = true;
  out.clamp_request = true;
  out.motion_enable = true;
  driver.writeOutputs(out);
  EXPECT_EQ(driver.readOutputs(), out);
  EXPECT_TRUE(plc_.coil(Coil::MotionEnable));
  EXPECT_FALSE(plc_.coil(Coil::StackLightAmber));
  const PlcInputs in = driver.readInputs();
  EXPECT_FALSE(in.laser_shutter_closed) << "the shutter follows its request";
  EXPECT_TRUE(in.part_clamped) << "the clamp follows its request";

  driver.setOutput(Coil::StackLightRed, false);
  driver.setOutput(Coil::StackLightAmber, true);
  out.stack_light_red = false;
  out.stack_light_amber = true;
  EXPECT_EQ(driver.readOutputs(), out);
}

TEST_F(ModbusPlcTest, ThePlcSeesTheStationHeartbeat) {
  ModbusPlc driver(options());
  driver.connect();  // the watchdog thread writes the heartbeat every poll period
  ASSERT_TRUE(waitUntil([&] { return plc_.stationHeartbeatChanges() >= 3; }))
      << "heartbeat changes seen: " << plc_.stationHeartbeatChanges();
  const std::uint16_t written = driver.writeHeartbeat();
  const PlcInputs in = driver.readInputs();
  // The watchdog thread may have written a newer beat in between; never an older one or none.
  EXPECT_NE(in.station_heartbeat_echo, 0);
  EXPECT_GE(static_cast<std::int16_t>(in.station_heartbeat_echo - written), 0);
  EXPECT_EQ(plc_.inputRegister(InputRegister::StationHeartbeatEcho),
            plc_.holdingRegister(HoldingRegister::StationHeartbeat));
  // The PLC's own heartbeat moves too: its program runs.
  EXPECT_TRUE(waitUntil([&] { return driver.readInputs().plc_heartbeat != in.plc_heartbeat; }));
}

TEST_F(ModbusPlcTest, DoorOpenedMidScanClosesTheShutterAndDropsMotion) {
  EventRecorder recorder;  // declared first: it must outlive the driver's watchdog thread
  ModbusPlc driver(options());
  recorder.attach(driver);
  driver.connect();
  PlcOutputs scanning;
  scanning.stack_light_green = true;
  scanning.laser_shutter_open_request = true;
  scanning.motion_enable = true;
  driver.writeOutputs(scanning);
  ASSERT_FALSE(driver.readInputs().laser_shutter_closed);
  // The watchdog must have its baseline (a first read) before the door opens.
  ASSERT_TRUE(waitUntil([&] { return driver.lastInputs().has_value(); }));

  const auto before = std::chrono::system_clock::now();
  plc_.openDoor();
  const std::optional<PlcEvent> opened = recorder.waitFor(PlcEventKind::DoorOpened);
  ASSERT_TRUE(opened) << "no door-opened event";
  EXPECT_GE(opened->when, before);
  EXPECT_LE(opened->when, std::chrono::system_clock::now());
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::InterlockTripped));

  const PlcInputs in = driver.readInputs();
  EXPECT_FALSE(in.door_closed);
  EXPECT_TRUE(in.laser_shutter_closed);
  EXPECT_TRUE(in.has(FaultBit::DoorOpen));
  EXPECT_TRUE(in.interlockTripped());
  const PlcOutputs out = driver.readOutputs();
  EXPECT_FALSE(out.motion_enable);
  EXPECT_FALSE(out.laser_shutter_open_request);
  EXPECT_TRUE(out.stack_light_green) << "the interlock leaves the other outputs alone";
  EXPECT_TRUE(hasEvent(driver.events(), PlcEventKind::DoorOpened));
  EXPECT_TRUE(hasFault(driver.faults(), "interlock"));
  EXPECT_EQ(driver.state(), DeviceState::Faulted);

  // Writing motion enable while the door is open does not take.
  driver.setOutput(Coil::MotionEnable, true);
  EXPECT_FALSE(driver.readOutputs().motion_enable);

  // Closing the door clears the trip, but nothing restarts by itself.
  plc_.closeDoor();
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::DoorClosed));
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::InterlockCleared));
  EXPECT_FALSE(driver.readOutputs().motion_enable);
  driver.writeOutputs(scanning);
  EXPECT_EQ(driver.readOutputs(), scanning);
}

TEST_F(ModbusPlcTest, EStopAndLightCurtainAreEventsToo) {
  EventRecorder recorder;  // declared first: it must outlive the driver's watchdog thread
  ModbusPlc driver(options());
  recorder.attach(driver);
  driver.connect();
  ASSERT_TRUE(waitUntil([&] { return driver.lastInputs().has_value(); }));
  plc_.breakEStopChain();
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::EStopBroken));
  plc_.interruptLightCurtain();
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::LightCurtainInterrupted));
  plc_.restoreEStopChain();
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::EStopRestored));
  EXPECT_TRUE(driver.readInputs().has(FaultBit::LightCurtainInterrupted));
  plc_.clearLightCurtain();
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::LightCurtainCleared));
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::InterlockCleared));
  EXPECT_FALSE(driver.readInputs().interlockTripped());
}

}  // namespace
}  // namespace stampscan::plc_test
