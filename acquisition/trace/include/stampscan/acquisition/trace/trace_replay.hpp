// Trace replay: plays a recorded MCAP trace to a consumer as if the devices were sending it again,
// with the original timing (speed 1), faster (speed N), or as fast as possible (speed 0).
//
// Messages go out in file order (the order the recorder received them); message i is due at
//   start + (log_time_i - log_time_first) / speed
// on the replay clock, and is handed over once the clock reaches that. A message whose log time is
// earlier than one already played is due at once. Lateness (how long after its due time a message
// went out) is reported, so a consumer too slow for real time shows up in the statistics.
//
// The clock is injectable: tests give a fake one and check the schedule without real waiting.
// stop() may be called from any thread (or from the consumer) and wakes a replay that is waiting.
#pragma once

#include "stampscan/acquisition/trace/mcap_reader.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>

namespace stampscan::trace {

struct ReplayClock {
  std::function<std::int64_t()> now_ns;              // a monotonic clock, ns
  std::function<void(std::int64_t)> sleep_until_ns;  // returns once now_ns() has reached the argument
};

// A TraceReplayer given no clock uses std::chrono::steady_clock with a sleep that stop() interrupts.

struct ReplayOptions {
  double speed = 1.0;          // 1: original timing, N: N times faster, 0: as fast as possible
  ReadOptions read;     // channel, topic and log-time filters
};

struct ReplayStats {
  std::uint64_t messages = 0;           // handed to the consumer
  std::uint64_t first_log_time_ns = 0;  // of the first and last message played
  std::uint64_t last_log_time_ns = 0;
  std::int64_t wall_ns = 0;             // replay clock time from the first message to the last
  std::int64_t max_lateness_ns = 0;
  double mean_lateness_ns = 0;
  bool stopped = false;                 // stop() or the consumer ended the replay early
  TraceHealth health;            // what the reader found in the trace

  std::uint64_t spanNs() const { return messages ? last_log_time_ns - first_log_time_ns : 0; }
};

class TraceReplayer {
 public:
  // Returns false to stop the replay.
  using Consumer = std::function<bool(const TraceMessage&)>;

  // Opens the trace (throws std::runtime_error naming it when it cannot); std::invalid_argument for
  // a negative or non-finite speed. Without a clock (both functions empty) it uses steady_clock.
  explicit TraceReplayer(const std::filesystem::path& trace, ReplayOptions options = {}, ReplayClock clock = {});

  // Plays the whole trace (or until stopped); blocks. Damaged or cut traces play what is readable.
  ReplayStats run(const Consumer& consumer);
  void stop();

 private:
  void sleepUntil(std::int64_t due_ns);

  McapReader reader_;
  ReplayOptions options_;
  ReplayClock clock_;
  bool own_clock_ = false;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
};

}  // namespace stampscan::trace
