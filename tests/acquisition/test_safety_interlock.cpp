// The door opened mid-scan: the virtual PLC trips its interlock (shutter closed, motion enable off),
// the PLC driver reports the event, the station's interlock aborts the CMM's move, and the event is
// logged; after the door closes and the faults are cleared the CMM moves again.
#include "stampscan/acquisition/safety_interlock.hpp"
#include "stampscan/sim/virtual_cmm.hpp"
#include "stampscan/sim/virtual_plc.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <thread>

namespace {

using namespace stampscan;
using namespace std::chrono_literals;

TEST(SafetyInterlock, DoorOpenedMidScanStopsTheMoveAndIsLogged) {
  sim::VirtualCmmConfig cmm_config;
  cmm_config.port = 0;
  sim::VirtualCmm virtual_cmm(cmm_config);
  virtual_cmm.start();
  sim::VirtualPlcOptions plc_options;
  plc_options.port = 0;
  sim::VirtualPlc virtual_plc(plc_options);
  virtual_plc.start();

  drivers::cmm::IppCmmOptions cmm_options;
  cmm_options.port = virtual_cmm.port();
  drivers::cmm::IppCmm cmm(cmm_options);
  cmm.connect();
  ASSERT_EQ(cmm.home(), drivers::cmm::MoveOutcome::Reached);
  cmm.setSpeed(20);  // a slow sweep: 200 mm take 10 s

  drivers::plc::ModbusPlcOptions plc_driver_options;
  plc_driver_options.port = virtual_plc.port();
  plc_driver_options.poll_period = 20ms;
  drivers::plc::ModbusPlc plc(plc_driver_options);
  acquisition::SafetyInterlock interlock(plc, cmm);
  plc.connect();
  // The scan: shutter open, motion enabled, a long move.
  plc.setOutput(drivers::plc::Coil::LaserShutterOpenRequest, true);
  plc.setOutput(drivers::plc::Coil::MotionEnable, true);
  const drivers::cmm::CmmPosition start = cmm.position();
  const drivers::cmm::CmmPosition target{start.x + 200, start.y, start.z};
  auto move = std::async(std::launch::async, [&] { return cmm.goTo(target); });
  std::this_thread::sleep_for(500ms);
  const auto opened = std::chrono::steady_clock::now();
  virtual_plc.openDoor();
  ASSERT_EQ(move.wait_for(3s), std::future_status::ready) << "the move was not stopped";
  EXPECT_EQ(move.get(), drivers::cmm::MoveOutcome::Aborted);
  EXPECT_LT(std::chrono::steady_clock::now() - opened, 1s);
  const drivers::cmm::CmmPosition stopped = cmm.position();
  EXPECT_GT(stopped.x, start.x + 1);
  EXPECT_LT(stopped.x, target.x - 50);
  // The PLC's side: shutter closed, motion enable dropped.
  EXPECT_FALSE(virtual_plc.coil(drivers::plc::Coil::LaserShutterOpenRequest));
  EXPECT_FALSE(virtual_plc.coil(drivers::plc::Coil::MotionEnable));
  // Logged.
  EXPECT_TRUE(interlock.tripped());
  bool logged = false;
  for (const auto& e : interlock.events()) logged |= e.what.find("motion aborted") != std::string::npos;
  EXPECT_TRUE(logged);
  // Recovery: the door closes, the faults are cleared, the CMM moves again.
  virtual_plc.closeDoor();
  plc.clearFaults();
  cmm.clearFaults();
  interlock.reset();
  EXPECT_EQ(cmm.goTo({stopped.x + 5, stopped.y, stopped.z}, 100.0), drivers::cmm::MoveOutcome::Reached);
  plc.disconnect();  // before the interlock goes: its callback must not outlive it
  cmm.disconnect();
}

}  // namespace
