// A progress line on stderr when it is a terminal; silent otherwise (logs and CI stay clean).
#pragma once

#include <mutex>
#include <string>

namespace stampscan::jobs {

class ProgressBar {
 public:
  ProgressBar();
  ~ProgressBar();
  // Thread-safe; redraws at most once per percent.
  void update(const std::string& stage, double fraction);
  void finish();

 private:
  std::mutex mutex_;
  bool enabled_;
  bool drawn_ = false;
  int last_percent_ = -1;
  std::string last_stage_;
};

}  // namespace stampscan::jobs
