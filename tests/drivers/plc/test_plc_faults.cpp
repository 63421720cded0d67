// Faults between the driver and the virtual PLC: slow replies, a silent PLC, the PLC's own heartbeat
// watchdog, a dropped connection, and nobody listening.
#include <gtest/gtest.h>

#include <stdexcept>

#include "plc_test_support.hpp"

namespace stampscan::plc_test {
namespace {

using drivers::DeviceError;
using drivers::DeviceFault;
using drivers::plc::Coil;
using drivers::plc::FaultBit;

using PlcFaultTest = PlcFixture;

TEST_F(PlcFaultTest, DelayedRepliesAreReportedAsTimeout) {
  ModbusPlcOptions opts = options();
  opts.watchdog = false;  // this test is about one request, not about the watchdog
  opts.response_timeout = 100ms;
  ModbusPlc driver(opts);
  driver.connect();
  plc_.setReplyDelay(300ms);
  const Clock::time_point start = Clock::now();
  try {
    driver.readInputs();
    FAIL() << "a reply delayed past the response timeout was accepted";
  } catch (const DeviceError& error) {
    EXPECT_EQ(error.code(), "timeout") << error.what();
    EXPECT_NE(std::string(error.what()).find("127.0.0.1"), std::string::npos) << error.what();
  }
  EXPECT_LT(Clock::now() - start, 290ms) << "the driver waited for the late reply";
  ASSERT_FALSE(driver.faults().empty());
  EXPECT_EQ(driver.faults().back().code, "timeout");

  // Prompt replies again: the next request works (on a fresh connection, not fooled by the late reply).
  plc_.setReplyDelay(0ms);
  EXPECT_TRUE(driver.readInputs().door_closed);
}

TEST_F(PlcFaultTest, SilentPlcStopsTheScanWithinTheSilenceLimit) {
  ModbusPlcOptions opts = options();
  opts.silence_limit = 300ms;
  // The callback's state and the recorder are declared before the driver: they must outlive its
  // watchdog thread.
  std::mutex mutex;
  std::condition_variable stopped;
  std::vector<DeviceFault> stops;
  EventRecorder recorder;
  ModbusPlc driver(opts);
  driver.setStopCallback([&](const DeviceFault& fault) {
    {
      std::lock_guard lock(mutex);
      stops.push_back(fault);
    }
    stopped.notify_all();
  });
  recorder.attach(driver);
  driver.connect();
  ASSERT_TRUE(waitUntil([&] { return driver.lastInputs().has_value(); }));

  const Clock::time_point silent_from = Clock::now();
  plc_.setSilent(true);
  {
    std::unique_lock lock(mutex);
    ASSERT_TRUE(stopped.wait_for(lock, 2s, [&] { return !stops.empty(); })) << "no stop";
  }
  const Clock::duration waited = Clock::now() - silent_from;
  // The last answer came at most one poll period before the silence began.
  EXPECT_LE(waited, opts.silence_limit + 150ms);
  EXPECT_GE(waited, opts.silence_limit - opts.poll_period - 10ms);
  EXPECT_EQ(stops.front().code, "plc-silent");
  EXPECT_TRUE(hasFault(driver.faults(), "plc-silent"));
  EXPECT_TRUE(hasEvent(driver.events(), PlcEventKind::PlcSilent));

  // The PLC answers again: the watchdog notices, and the stop was not repeated meanwhile.
  plc_.setSilent(false);
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::PlcAnswering));
  std::lock_guard lock(mutex);
  EXPECT_EQ(stops.size(), 1U);
}

TEST_F(PlcFaultTest, PlcDropsMotionEnableWhenTheStationHeartbeatStops) {
  ModbusPlcOptions opts = options();
  opts.plc_watchdog_timeout_ms = 150;
  ModbusPlc driver(opts);
  driver.connect();
  ASSERT_TRUE(waitUntil([&] { return plc_.stationHeartbeatChanges() >= 2; }));
  driver.setOutput(Coil::MotionEnable, true);
  ASSERT_TRUE(plc_.coil(Coil::MotionEnable));

  // The station dies: no more heartbeat (the connection closes too, which the PLC ignores).
  driver.disconnect();
  const Clock::time_point stopped = Clock::now();
  ASSERT_TRUE(waitUntil([&] { return !plc_.coil(Coil::MotionEnable); }, 2s))
      << "the PLC kept motion enabled without a heartbeat";
  const Clock::duration waited = Clock::now() - stopped;
  EXPECT_GE(waited, 150ms - opts.poll_period - 10ms) << "tripped before the watchdog timeout";
  EXPECT_LE(waited, 150ms + 150ms);
  EXPECT_TRUE(plc_.interlockTripped());
  EXPECT_NE(plc_.faultWord() & drivers::plc::mask(FaultBit::StationHeartbeatLost), 0);

  // The station comes back: the heartbeat clears the trip, motion stays off until asked for.
  driver.connect();
  EXPECT_TRUE(waitUntil([&] { return !plc_.interlockTripped(); }));
  EXPECT_FALSE(plc_.coil(Coil::MotionEnable));
}

TEST_F(PlcFaultTest, ReconnectsAfterADroppedConnection) {
  EventRecorder recorder;  // declared first: it must outlive the driver's watchdog thread
  ModbusPlc driver(options());
  recorder.attach(driver);
  driver.connect();
  ASSERT_TRUE(waitUntil([&] { return plc_.connectionCount() == 2; }))  // API + watchdog
      << plc_.connectionCount() << " connections";

  plc_.dropConnections();
  ASSERT_TRUE(waitUntil([&] { return plc_.connectionCount() == 0; }));
  EXPECT_TRUE(driver.readInputs().door_closed) << "the request reconnects and retries";
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::ConnectionLost));
  EXPECT_TRUE(recorder.waitFor(PlcEventKind::Reconnected));
  EXPECT_TRUE(waitUntil([&] { return plc_.connectionCount() == 2; }))
      << "the watchdog did not reconnect";
  const std::uint64_t beats = plc_.stationHeartbeatChanges();
  EXPECT_TRUE(waitUntil([&] { return plc_.stationHeartbeatChanges() > beats; }));
  EXPECT_FALSE(hasFault(driver.faults(), "plc-silent"));
  EXPECT_FALSE(hasFault(driver.faults(), "disconnected"));
}

TEST(PlcConnect, NobodyListeningIsAClearError) {
  int port = 0;
  {
    VirtualPlc plc(virtualPlcOptions());
    plc.start();
    port = plc.port();
  }  // stopped: the port is closed now
  ModbusPlc driver(driverOptions(port));
  try {
    driver.connect();
    FAIL() << "connected to a closed port";
  } catch (const DeviceError& error) {
    EXPECT_EQ(error.code(), "disconnected") << error.what();
    EXPECT_NE(std::string(error.what()).find(std::to_string(port)), std::string::npos)
        << error.what();
  }
  EXPECT_EQ(driver.state(), drivers::DeviceState::Faulted);
  EXPECT_FALSE(driver.check());
}

TEST(PlcConnect, OptionsThatCannotWorkAreRefused) {
  ModbusPlcOptions no_port = driverOptions(0);
  EXPECT_THROW(ModbusPlc{no_port}, std::invalid_argument);
  ModbusPlcOptions no_timeout = driverOptions(1502);
  no_timeout.response_timeout = 0ms;
  EXPECT_THROW(ModbusPlc{no_timeout}, std::invalid_argument);
}

TEST(PlcConnect, VirtualPlcStopsCleanlyWithClientsConnected) {
  VirtualPlc plc(virtualPlcOptions());
  plc.start();
  ModbusPlc driver(driverOptions(plc.port()));
  driver.connect();
  ASSERT_TRUE(waitUntil([&] { return plc.connectionCount() == 2; }));
  plc.setReplyDelay(1000ms);  // a connection thread is waiting to reply when the stop comes
  const Clock::time_point start = Clock::now();
  plc.stop();
  EXPECT_LT(Clock::now() - start, 500ms) << "stop waited for a delayed reply";
  EXPECT_FALSE(plc.running());
  EXPECT_EQ(plc.connectionCount(), 0U);
}

}  // namespace
}  // namespace stampscan::plc_test
