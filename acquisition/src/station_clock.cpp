#include "stampscan/acquisition/station_clock.hpp"

#include <chrono>

namespace stampscan::acquisition {

std::int64_t StationClock::steadyNow() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

StationClock::StationClock()
    : StationClock([] {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
      }) {}

StationClock::StationClock(Source now) : now_(std::move(now)) {
  // Read the two clocks close together: the smallest gap of a few tries.
  std::int64_t best_gap = INT64_MAX;
  for (int i = 0; i < 5; ++i) {
    const std::int64_t s0 = steadyNow(), station = now_(), s1 = steadyNow();
    if (s1 - s0 < best_gap) {
      best_gap = s1 - s0;
      steady_to_station_ = station - (s0 + (s1 - s0) / 2);
    }
  }
}

}  // namespace stampscan::acquisition
