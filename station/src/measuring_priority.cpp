#include "stampscan/station/measuring_priority.hpp"

#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

namespace stampscan::station {
namespace {

constexpr const char* kSessionGroup = "/proc/self/autogroup";  // "/autogroup-N nice K" where the kernel has it

bool setSessionNice(int nice) {
  std::ofstream out(kSessionGroup);
  out << nice << std::flush;
  return static_cast<bool>(out);
}

}  // namespace

std::optional<int> sessionNice() {
  std::ifstream in(kSessionGroup);
  std::string group, word;
  int nice = 0;
  if (in >> group >> word >> nice && word == "nice") return nice;
  return std::nullopt;
}

MeasuringPriority::MeasuringPriority(MeasuringPriority&& other) noexcept
    : raised(other.raised), nice(other.nice), reason(std::move(other.reason)),
      session_nice_before_(std::exchange(other.session_nice_before_, std::nullopt)) {}

MeasuringPriority::~MeasuringPriority() {
  if (session_nice_before_) setSessionNice(*session_nice_before_);
}

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
  if (errno != 0 || now > kMeasuringNice) {
    // Linux keeps a nice value per thread (PRIO_PROCESS with an id names one thread), so each
    // thread already running is raised by its id; threads started later inherit their starter's.
    std::error_code ec;
    std::filesystem::directory_iterator tasks("/proc/self/task", ec);
    if (ec) {
      p.reason = "/proc/self/task cannot be read: " + ec.message();
      return p;
    }
    for (const auto& task : tasks) {
      const auto tid = static_cast<id_t>(std::stoul(task.path().filename().string()));
      if (setpriority(PRIO_PROCESS, tid, kMeasuringNice) != 0 && errno != ESRCH) {  // ESRCH: a thread just ended
        p.reason = errno == EACCES || errno == EPERM
                       ? "raising it needs root or CAP_SYS_NICE; the panel's service unit sets it"
                       : std::string(std::strerror(errno));
        return p;
      }
    }
    p.nice = kMeasuringNice;
  }
  p.raised = true;
  // The session's share, where the kernel groups by session (its setting may be off; then nothing
  // to do). A refusal here leaves the threads' raise, which still counts within the session.
  if (const std::optional<int> session = sessionNice(); session && *session > kMeasuringNice)
    if (setSessionNice(kMeasuringNice)) p.session_nice_before_ = session;
  return p;
}

}  // namespace stampscan::station
