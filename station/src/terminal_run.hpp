// A run on the cell (calibrate, verify) as a terminal shows it: the checks before motion, a progress
// bar with the step (none with quiet), the safety events; and the run itself with Ctrl-C and SIGTERM
// turned into an operator abort (stop_signals.hpp), the bar ended on every way out.
#pragma once

#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/jobs/progress.hpp"
#include "stop_signals.hpp"

#include <cstdio>
#include <string>

namespace stampscan::station {

class TerminalRunObserver final : public acquisition::ScanObserver {
 public:
  explicit TerminalRunObserver(bool quiet) : quiet_(quiet) {}
  void checkPassed(const std::string& what) override { std::printf("  check       %s\n", what.c_str()); }
  void progress(const acquisition::ScanProgress& p) override {
    if (quiet_) return;
    bar_.update(p.doing, p.steps ? static_cast<double>(p.step) / static_cast<double>(p.steps) : 0.0);
  }
  void safetyEvent(acquisition::FaultKind, const std::string& what) override { std::printf("  safety      %s\n", what.c_str()); }
  void finish() { bar_.finish(); }

 private:
  bool quiet_;
  jobs::ProgressBar bar_;
};

// `run()`'s result; a signal meanwhile calls `abort(reason)` from the guard's thread.
template <typename Run, typename Abort>
auto runAbortable(TerminalRunObserver& observer, Run run, Abort abort) {
  struct EndBar {
    TerminalRunObserver& observer;
    ~EndBar() { observer.finish(); }
  } end_bar{observer};
  const StopSignalGuard stop(abort);
  return run();
}

}  // namespace stampscan::station
