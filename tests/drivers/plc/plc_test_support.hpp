// Shared by the PLC suites: a virtual PLC on an ephemeral loopback port, driver options with short
// timeouts (the suite must stay fast), bounded waits on conditions, and an event recorder.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "stampscan/drivers/plc/modbus_plc.hpp"
#include "stampscan/sim/virtual_plc.hpp"

namespace stampscan::plc_test {

using namespace std::chrono_literals;
using drivers::plc::ModbusPlc;
using drivers::plc::ModbusPlcOptions;
using drivers::plc::PlcEvent;
using drivers::plc::PlcEventKind;
using sim::VirtualPlc;
using Clock = std::chrono::steady_clock;

// Polls a condition until it holds or the limit passes; true when it held. Polling (every 2 ms)
// rather than a notification, because most conditions live in the virtual PLC's register image.
inline bool waitUntil(const std::function<bool()>& condition, Clock::duration limit = 2s) {
  const Clock::time_point deadline = Clock::now() + limit;
  while (!condition()) {
    if (Clock::now() >= deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

inline sim::VirtualPlcOptions virtualPlcOptions() {
  sim::VirtualPlcOptions options;
  options.port = 0;  // ephemeral: suites may run in parallel
  options.cycle = 5ms;
  return options;
}

inline ModbusPlcOptions driverOptions(int port) {
  ModbusPlcOptions options;
  options.port = port;
  options.response_timeout = 200ms;
  options.poll_period = 20ms;
  options.silence_limit = 400ms;
  return options;
}

// Collects the driver's events as they are delivered (on the watchdog thread).
class EventRecorder {
 public:
  void attach(ModbusPlc& plc) {
    plc.setEventCallback([this](const PlcEvent& event) {
      {
        std::lock_guard lock(mutex_);
        events_.push_back(event);
      }
      arrived_.notify_all();
    });
  }

  // The first event of this kind, waiting up to `limit` for it.
  std::optional<PlcEvent> waitFor(PlcEventKind kind, Clock::duration limit = 2s) {
    std::unique_lock lock(mutex_);
    std::optional<PlcEvent> found;
    arrived_.wait_for(lock, limit, [&] {
      const auto it = std::find_if(events_.begin(), events_.end(),
                                   [&](const PlcEvent& event) { return event.kind == kind; });
      if (it != events_.end()) found = *it;
      return found.has_value();
    });
    return found;
  }

 private:
  std::mutex mutex_;
  std::condition_variable arrived_;
  std::vector<PlcEvent> events_;
};

inline bool hasEvent(const std::vector<PlcEvent>& events, PlcEventKind kind) {
  return std::any_of(events.begin(), events.end(),
                     [&](const PlcEvent& event) { return event.kind == kind; });
}

inline bool hasFault(const std::vector<drivers::DeviceFault>& faults, const std::string& code) {
  return std::any_of(faults.begin(), faults.end(),
                     [&](const drivers::DeviceFault& fault) { return fault.code == code; });
}

// A started virtual PLC and a driver pointed at it (not yet connected).
class PlcFixture : public ::testing::Test {
 protected:
  void SetUp() override { plc_.start(); }
  ModbusPlcOptions options() const { return driverOptions(plc_.port()); }

  VirtualPlc plc_{virtualPlcOptions()};
};

}  // namespace stampscan::plc_test
