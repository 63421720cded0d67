#include "stampscan/acquisition/trace/trace_replay.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace stampscan::trace {

namespace {
std::int64_t steadyNow() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
std::chrono::steady_clock::time_point steadyAt(std::int64_t ns) {
  return std::chrono::steady_clock::time_point(
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::nanoseconds(ns)));
}
}  // namespace

TraceReplayer::TraceReplayer(const std::filesystem::path& trace, ReplayOptions options, ReplayClock clock)
    : reader_(trace), options_(std::move(options)), clock_(std::move(clock)) {
  if (!(options_.speed >= 0) || !std::isfinite(options_.speed))
    throw std::invalid_argument("trace replay speed must be 0 (as fast as possible) or positive, got " +
                                std::to_string(options_.speed));
  if (!clock_.now_ns && !clock_.sleep_until_ns) {
    clock_.now_ns = steadyNow;
    own_clock_ = true;  // sleeps on wake_, so that stop() cuts a long wait short
  } else if (!clock_.now_ns || !clock_.sleep_until_ns) {
    throw std::invalid_argument("a replay clock needs both now_ns and sleep_until_ns");
  }
}

void TraceReplayer::stop() {
  stop_ = true;
  { const std::lock_guard<std::mutex> lock(mutex_); }  // a run() between its check and its wait sees stop_
  wake_.notify_all();
}

void TraceReplayer::sleepUntil(std::int64_t due_ns) {
  if (!own_clock_) return clock_.sleep_until_ns(due_ns);
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait_until(lock, steadyAt(due_ns), [this] { return stop_.load(); });
}

ReplayStats TraceReplayer::run(const Consumer& consumer) {
  ReplayStats stats;
  bool first = true;
  std::int64_t start = 0, last_out = 0;
  std::uint64_t latest_log = 0;
  long double lateness_sum = 0;
  const long double speed = options_.speed;
  stats.health = reader_.readMessages(
      [&](const TraceMessage& m) {
        if (stop_) return false;
        std::int64_t now = clock_.now_ns();
        if (first) {
          first = false;
          start = now;
          stats.first_log_time_ns = latest_log = m.log_time;
        }
        // Due time on the replay clock; out-of-order and speed-0 messages are due at once.
        std::int64_t due = now;
        if (speed > 0 && m.log_time >= latest_log)
          due = start + static_cast<std::int64_t>(std::llround(static_cast<long double>(m.log_time - stats.first_log_time_ns) / speed));
        latest_log = std::max(latest_log, m.log_time);
        if (now < due) {
          sleepUntil(due);
          if (stop_) return false;
          now = clock_.now_ns();
        }
        const std::int64_t late = std::max<std::int64_t>(0, now - due);
        stats.max_lateness_ns = std::max(stats.max_lateness_ns, late);
        lateness_sum += late;
        ++stats.messages;
        stats.last_log_time_ns = m.log_time;
        last_out = now;
        return consumer(m) && !stop_;
      },
      options_.read);
  stats.stopped = stats.health.stopped;
  stats.wall_ns = stats.messages ? last_out - start : 0;
  stats.mean_lateness_ns = stats.messages ? static_cast<double>(lateness_sum / stats.messages) : 0.0;
  return stats;
}

}  // namespace stampscan::trace
