#include "stampscan/station/measuring_priority.hpp"

#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

namespace stampscan::station {

std::string MeasuringPriority::describe() const {
  if (raised) return "nice " + std::to_string(nice) + ": the measurement goes before other work on this computer";
  return "nice " + std::to_string(nice) + " (not raised: " + reason +
         "); other work on this computer may delay the verdict";
}

MeasuringPriority raiseMeasuringPriority() {
  MeasuringPriority p;
  errno = 0;
  const int now = getpriority(PRIO_PROCESS, 0);
  p.nice = errno == 0 ? now : 0;
  if (errno == 0 && now <= kMeasuringNice) {
    p.raised = true;
    return p;
  }
  // Linux keeps a nice value per thread (PRIO_PROCESS with an id names one thread), so each thread
  // already running is raised by its id; threads started later inherit their starter's.
  std::error_code ec;
  std::filesystem::directory_iterator tasks("/proc/self/task", ec);
  if (ec) {
    p.reason = "/proc/self/task cannot be read: " + ec.message();
    return p;
  }
  for (const auto& task : tasks) {
    const id_t tid = static_cast<id_t>(std::stoul(task.path().filename().string()));
    if (setpriority(PRIO_PROCESS, tid, kMeasuringNice) != 0) {
      p.reason = errno == EACCES || errno == EPERM ? "raising it needs root or CAP_SYS_NICE; the panel's service unit sets it"
                                                   : std::string(std::strerror(errno));
      if (errno != ESRCH) return p;  // a thread that has just ended is no refusal
    }
  }
  p.raised = true;
  p.nice = kMeasuringNice;
  p.reason.clear();
  return p;
}

}  // namespace stampscan::station
