// A plan run on the cell into a trace file of its own, abortable from another thread: what the
// calibration and verification jobs share (a scan job also tees its messages to the live
// measurement, so it drives its runner itself).
//
// Thread safety: run() blocks; abort() may be called from any other thread, before or during run().
#pragma once

#include "stampscan/acquisition/cell.hpp"
#include "stampscan/acquisition/scan_runner.hpp"

#include <filesystem>
#include <mutex>
#include <optional>
#include <string>

namespace stampscan::jobs {

class TracedRun {
 public:
  TracedRun(acquisition::Cell& cell, acquisition::ScanObserver* observer) : cell_(cell), observer_(observer) {}

  // Runs the plan into `trace_file` (MCAP, written as the data arrives). A run refused before motion
  // (acquisition::ScanError) leaves no file and rethrows; an aborted run keeps its trace and returns
  // completed = false.
  acquisition::ScanRunResult run(const acquisition::ScanPlan& plan, const acquisition::ScanRunParams& params,
                                 const std::filesystem::path& trace_file);
  void abort(const std::string& reason);

 private:
  acquisition::Cell& cell_;
  acquisition::ScanObserver* observer_;
  std::mutex mutex_;
  acquisition::ScanRunner* runner_ = nullptr;  // while a run is under way
  std::optional<std::string> pending_abort_;
};

}  // namespace stampscan::jobs
