#include "stampscan/jobs/traced_run.hpp"

#include "stampscan/acquisition/trace/mcap_writer.hpp"
#include "stampscan/acquisition/trace/trace_recorder.hpp"

namespace stampscan::jobs {

void TracedRun::abort(const std::string& reason) {
  std::lock_guard lock(mutex_);
  if (runner_)
    runner_->abort(reason);
  else if (!pending_abort_)
    pending_abort_ = reason;
}

acquisition::ScanRunResult TracedRun::run(const acquisition::ScanPlan& plan, const acquisition::ScanRunParams& params,
                                          const std::filesystem::path& trace_file) {
  trace::McapWriter writer(trace_file);
  trace::TraceRecorder recorder(writer);
  const acquisition::StationClock clock;
  acquisition::ScanRunner runner(cell_.devices(), recorder, clock, observer_);
  const auto attach = [&](acquisition::ScanRunner* r) {
    std::lock_guard lock(mutex_);
    runner_ = r;
    if (r != nullptr && pending_abort_) r->abort(*pending_abort_);
  };
  attach(&runner);
  acquisition::ScanRunResult result;
  try {
    result = runner.run(plan, params);
  } catch (const acquisition::ScanError&) {
    attach(nullptr);
    writer.close();
    std::error_code ignored;
    std::filesystem::remove(trace_file, ignored);  // refused before motion: nothing to keep
    throw;
  } catch (...) {
    attach(nullptr);
    throw;
  }
  attach(nullptr);
  writer.close();
  return result;
}

}  // namespace stampscan::jobs
