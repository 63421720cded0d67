// Shared by the PLC and CMM suites for peers and conditions a device or server must survive:
// loopback listeners (one whose queue is full, like a device that never accepts), a process out of
// file descriptors, and the CPU time the process uses (an accept loop that spins shows there).
//
// DescriptorExhaustion is process-wide (RLIMIT_NOFILE and the descriptor table): each test runs in
// a process of its own under CTest (gtest_discover_tests), so nothing else is starved by it.
#pragma once

#include <arpa/inet.h>
#include <dirent.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <ctime>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace stampscan::test {

inline sockaddr_in loopbackAddress(int port) {
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return address;
}

// A listening socket on an ephemeral loopback port, written to `port`.
inline int listenOnLoopback(int backlog, int& port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in address = loopbackAddress(0);
  socklen_t length = sizeof address;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
      ::listen(fd, backlog) != 0 || ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0)
    throw std::runtime_error("cannot listen on loopback");
  port = ntohs(address.sin_port);
  return fd;
}

// A port where connecting neither succeeds nor fails, as with a device that is off or unreachable:
// a listen queue that is full and never drained, so the kernel drops further SYNs.
class UnansweredPort {
 public:
  UnansweredPort() : listener_(listenOnLoopback(0, port_)) {
    for (int i = 0; i < 4; ++i) {
      const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
      const sockaddr_in address = loopbackAddress(port_);
      ::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address);
      fillers_.push_back(fd);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the fillers' handshakes fill the queue
  }
  ~UnansweredPort() {
    for (const int fd : fillers_) ::close(fd);
    ::close(listener_);
  }
  UnansweredPort(const UnansweredPort&) = delete;
  UnansweredPort& operator=(const UnansweredPort&) = delete;
  int port() const { return port_; }

 private:
  int port_ = 0;
  int listener_;
  std::vector<int> fillers_;
};

class DescriptorExhaustion {
 public:
  // Lowers the soft limit to a little above the highest descriptor in use (so that a few opens
  // suffice), then opens /dev/null until the limit is reached.
  DescriptorExhaustion() {
    ::getrlimit(RLIMIT_NOFILE, &saved_);
    rlimit lowered = saved_;
    lowered.rlim_cur = std::min<rlim_t>(saved_.rlim_cur, static_cast<rlim_t>(highestOpenDescriptor() + 16));
    ::setrlimit(RLIMIT_NOFILE, &lowered);
    for (;;) {
      const int fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
      if (fd < 0) break;
      held_.push_back(fd);
    }
  }
  ~DescriptorExhaustion() { release(); }
  DescriptorExhaustion(const DescriptorExhaustion&) = delete;
  DescriptorExhaustion& operator=(const DescriptorExhaustion&) = delete;

  // Frees the descriptors and restores the limit.
  void release() {
    for (const int fd : held_) ::close(fd);
    held_.clear();
    ::setrlimit(RLIMIT_NOFILE, &saved_);
  }
  std::size_t held() const { return held_.size(); }

 private:
  static int highestOpenDescriptor() {
    int highest = 2;
    if (DIR* dir = ::opendir("/proc/self/fd")) {
      while (const dirent* entry = ::readdir(dir)) highest = std::max(highest, std::atoi(entry->d_name));
      ::closedir(dir);
    }
    return highest;
  }

  rlimit saved_{};
  std::vector<int> held_;
};

// CPU time used by the whole process (every thread) so far.
inline std::chrono::nanoseconds processCpuTime() {
  timespec t{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return std::chrono::seconds(t.tv_sec) + std::chrono::nanoseconds(t.tv_nsec);
}

}  // namespace stampscan::test
