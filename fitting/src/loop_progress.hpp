// A parallel loop's progress, told from its workers each time another 1/32 of it is done: the
// caller's progress callback shows it, and may stop the fit by throwing (a scan stopped while its
// surface is fitted): TBB cancels the loop's other tasks and carries the exception out of it, so a
// stop is answered within a thirty-second of a stage, not at its end.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <functional>
#include <string>
#include <utility>

namespace stampscan::fitting::detail {

class LoopProgress {
 public:
  using Callback = std::function<void(const std::string& stage, double fraction)>;
  LoopProgress(const Callback& callback, std::string stage, std::size_t total)
      : callback_(callback), stage_(std::move(stage)), total_(total) {}

  // `items` more of the loop are done (thread-safe).
  void add(std::size_t items) {
    if (!callback_ || total_ == 0) return;
    const std::size_t done = done_.fetch_add(items) + items;
    const unsigned step = static_cast<unsigned>(kSteps * std::min(done, total_) / total_);
    unsigned last = reported_.load();
    while (step > last)
      if (reported_.compare_exchange_weak(last, step)) {
        callback_(stage_, static_cast<double>(step) / kSteps);
        return;
      }
  }

 private:
  static constexpr std::size_t kSteps = 32;
  const Callback& callback_;
  std::string stage_;
  std::size_t total_;
  std::atomic<std::size_t> done_{0};
  std::atomic<unsigned> reported_{0};
};

}  // namespace stampscan::fitting::detail
