// Ctrl-C and SIGTERM during a long run on the cell (scan, calibrate, verify): an operator abort with
// the run's clean ending (motion aborted, shutter closed, the trace closed). The signal handler only
// sets a flag; a watcher thread turns it into a call of the job's abort(), which a handler may not
// make. The previous handlers are back when the guard goes.
#pragma once

#include <functional>
#include <string>
#include <thread>

namespace stampscan::station {

class StopSignalGuard {
 public:
  // `abort` is called once, from the watcher thread, with "operator abort (Ctrl-C)" or "stopped (SIGTERM)".
  explicit StopSignalGuard(std::function<void(const std::string& reason)> abort);
  ~StopSignalGuard();
  StopSignalGuard(const StopSignalGuard&) = delete;
  StopSignalGuard& operator=(const StopSignalGuard&) = delete;

 private:
  using Handler = void (*)(int);
  Handler previous_int_, previous_term_;
  std::jthread watcher_;
};

}  // namespace stampscan::station
