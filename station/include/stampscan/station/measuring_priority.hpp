// The CPU for the measurement before other work on the cell's computer. A cell PC also runs the
// panel's browser, a database and the plant's software; at their equal share, the returns and
// views of a scan beside heavy work were fitted a minute after the last sweep instead of seconds.
// The commands that measure (scan, calibrate, verify, hmi) and the virtual cell that stands for the
// cell's controllers (`station sim serve`) raise their nice value to kMeasuringNice when the system
// lets them: as root, with CAP_SYS_NICE, or under the panel's service unit, whose Nice= sets it
// before the panel starts. Nice is a share, not a real-time class: the rest of the computer still
// runs, only later.
#pragma once

#include <optional>
#include <string>

namespace stampscan::station {

inline constexpr int kMeasuringNice = -19;

// Held for as long as the command measures. Linux shares the CPU between sessions first (the
// scheduler's autogroups: a terminal, a service) and by nice value only within one; so beside the
// threads' nice value the session's is raised too, and put back when this is destroyed.
class MeasuringPriority {
 public:
  MeasuringPriority() = default;
  MeasuringPriority(MeasuringPriority&& other) noexcept;
  MeasuringPriority& operator=(MeasuringPriority&&) = delete;
  ~MeasuringPriority();

  bool raised = false;  // the process runs at kMeasuringNice or above
  int nice = 0;         // its nice value now
  std::string reason;   // why it could not be raised, when it was not

  // One line for the command's output: what the measurement may expect of this computer.
  std::string describe() const;

 private:
  friend MeasuringPriority raiseMeasuringPriority();

// The session's nice value where the kernel shares the CPU by session first (its autogroups), or
// nothing where it does not.
std::optional<int> sessionNice();
  std::optional<int> session_nice_before_;  // the session's nice value this raised, to put back
};

// Raises every thread of this process (and so those it starts later) to kMeasuringNice, and the
// session's share when the kernel groups by session; a process already at or above it is left
// alone. Never fails: without the right it says why and runs on.
MeasuringPriority raiseMeasuringPriority();

// The session's nice value where the kernel shares the CPU by session first (its autogroups), or
// nothing where it does not.
std::optional<int> sessionNice();

}  // namespace stampscan::station
