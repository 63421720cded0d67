#include "stampscan/jobs/progress.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace stampscan::jobs {

ProgressBar::ProgressBar() : enabled_(isatty(STDERR_FILENO) == 1) {}
ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::update(const std::string& stage, double fraction) {
  if (!enabled_) return;
  std::lock_guard lock(mutex_);
  const int percent = static_cast<int>(std::lround(100.0 * fraction));
  if (stage == last_stage_ && percent == last_percent_) return;
  last_stage_ = stage;
  last_percent_ = percent;
  constexpr int kWidth = 30;
  const int filled = percent * kWidth / 100;
  std::fprintf(stderr, "\r  %-12s [%.*s%*s] %3d%%", stage.c_str(), filled, "##############################",
               kWidth - filled, "", percent);
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::finish() {
  std::lock_guard lock(mutex_);
  if (drawn_) std::fprintf(stderr, "\r%*s\r", 60, "");
  drawn_ = false;
}

}  // namespace stampscan::jobs
