// The station clock: the one time base of everything a scan records. Trace log times, the CMM's
// positions, the sweeps' windows and the devices' clock pairs are all on it. Drivers stamp what they
// receive with std::chrono::steady_clock (monotonic, immune to clock changes); fromSteady() puts
// those stamps on the station clock. The devices' own clocks (the digitizer's, the cameras') are
// related to it by ClockSync pairs in the trace, never converted in place.
//
// Injected: a test or a replay gives its own source of "now"; the default is the system clock in
// ns since the Unix epoch, so traces carry wall-clock dates. Thread-safe (const after construction).
#pragma once

#include <cstdint>
#include <functional>

namespace stampscan::acquisition {

class StationClock {
 public:
  using Source = std::function<std::int64_t()>;  // ns

  StationClock();                       // the system clock, ns since the Unix epoch
  explicit StationClock(Source now);

  std::int64_t now() const { return now_(); }
  // A std::chrono::steady_clock reading in ns (what the drivers stamp) on the station clock; the
  // two are related once, at construction, so the result is monotonic with the steady reading.
  std::int64_t fromSteady(std::int64_t steady_ns) const { return steady_ns + steady_to_station_; }
  static std::int64_t steadyNow();

 private:
  Source now_;
  std::int64_t steady_to_station_ = 0;
};

}  // namespace stampscan::acquisition
