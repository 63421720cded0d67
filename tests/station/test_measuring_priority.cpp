// The commands that measure take the CPU before other work when the system lets them
// (measuring_priority.hpp): every thread of the process, those already running too, or a reason.
// Each case runs in a child process, so the test's own priority stays as it was.
#include "stampscan/station/measuring_priority.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>

namespace stampscan::station::test {
namespace {

int threadNice(pid_t tid) { return getpriority(PRIO_PROCESS, static_cast<id_t>(tid)); }

// Runs `check` in a child process and returns its exit code (0: every expectation held).
template <typename Check>
int inChild(Check check) {
  std::fflush(nullptr);
  const pid_t child = fork();
  if (child == 0) _exit(check());
  int status = 0;
  waitpid(child, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 100;
}

TEST(MeasuringPriority, EveryThreadAlreadyRunningAndEveryLaterOneIsRaised) {
  if (geteuid() != 0) GTEST_SKIP() << "not root: raising a nice value needs root or CAP_SYS_NICE (the refusal is tested)";
  const int code = inChild([] {
    setpriority(PRIO_PROCESS, 0, 0);  // as an ordinary start, whatever the test runs at
    std::atomic<pid_t> early_tid{0};
    std::atomic<bool> done{false};
    std::thread early([&] {
      early_tid = static_cast<pid_t>(syscall(SYS_gettid));
      while (!done) std::this_thread::yield();
    });
    while (early_tid == 0) std::this_thread::yield();
    const std::optional<int> session_before = sessionNice();
    std::optional<MeasuringPriority> held(raiseMeasuringPriority());
    const MeasuringPriority& p = *held;
    // The session's share with it, while held, and as it was once the command is done.
    if (session_before && sessionNice() != std::min(*session_before, kMeasuringNice)) return 7;
    int later_nice = 1;
    std::thread later([&] { later_nice = threadNice(static_cast<pid_t>(syscall(SYS_gettid))); });
    later.join();
    const int early_nice = threadNice(early_tid);
    done = true;
    early.join();
    if (!p.raised || p.nice != kMeasuringNice) return 1;
    if (threadNice(static_cast<pid_t>(syscall(SYS_gettid))) != kMeasuringNice) return 2;
    if (early_nice != kMeasuringNice) return 3;
    if (later_nice != kMeasuringNice) return 4;
    if (p.describe().find("before other work") == std::string::npos) return 5;
    // A second call finds it raised and leaves it.
    if (!raiseMeasuringPriority().raised) return 6;
    held.reset();
    return sessionNice() == session_before ? 0 : 8;
  });
  EXPECT_EQ(code, 0) << "1: not raised, 2: this thread, 3: a thread started before, 4: a thread started after, "
                        "5: the line, 6: a second call, 7: the session not raised, 8: the session's not put back";
}

TEST(MeasuringPriority, WithoutTheRightItRunsOnAndSaysWhy) {
  const int code = inChild([] {
    // An ordinary user's process at the ordinary nice value.
    if (geteuid() == 0 && (setgid(65534) != 0 || setuid(65534) != 0)) return 10;
    if (getpriority(PRIO_PROCESS, 0) <= kMeasuringNice) return 11;
    const int before = getpriority(PRIO_PROCESS, 0);
    const MeasuringPriority p = raiseMeasuringPriority();
    if (p.raised) return 1;
    if (p.nice != before || getpriority(PRIO_PROCESS, 0) != before) return 2;
    if (p.reason.find("CAP_SYS_NICE") == std::string::npos) return 3;
    if (p.describe().find("not raised") == std::string::npos) return 4;
    return 0;
  });
  EXPECT_EQ(code, 0) << "1: raised, 2: the nice value changed, 3: no reason, 4: the line; 10: could not drop root, "
                        "11: the test itself runs raised";
}

}  // namespace
}  // namespace stampscan::station::test
