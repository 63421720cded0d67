// Shared by the CMM tests: a quick virtual CMM configuration, bounded waiting on a condition, and a
// raw line client that talks I++ DME the way a user with netcat would.
#pragma once

#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace stampscan::test {

using namespace std::chrono_literals;

// Moves of a few hundred mm take well under a second, so the suite stays quick.
inline sim::VirtualCmmConfig quickCmmConfig() {
  sim::VirtualCmmConfig c;
  c.port = 0;
  c.max_speed = 1000;
  c.default_speed = 500;
  c.max_accel = 5000;
  c.default_accel = 4000;
  c.power_on_position = {0, 0, 480};
  c.tool_change_seconds = 0.05;
  c.head_max_rate_deg_s = 180;  // a turn of 90 degrees in 0.75 s
  c.head_accel_deg_s2 = 720;
  return c;
}

// Polls `condition` until it holds or `limit` passes; true when it held. For conditions that another
// thread or process makes true, where there is nothing to wait on.
inline bool waitUntil(const std::function<bool()>& condition, std::chrono::milliseconds limit = 3000ms) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

// The expected duration of a straight move with a trapezoidal profile, written out independently
// of the virtual CMM's own planner.
inline double trapezoidSeconds(double distance, double speed, double accel) {
  if (distance * accel <= speed * speed) return 2 * std::sqrt(distance / accel);  // never reaches `speed`
  return distance / speed + speed / accel;
}

class RawIppClient {
 public:
  explicit RawIppClient(std::uint16_t port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) != 0) {
      ::close(fd_);
      throw std::runtime_error("cannot connect to the virtual CMM");
    }
  }
  ~RawIppClient() { ::close(fd_); }
  RawIppClient(const RawIppClient&) = delete;
  RawIppClient& operator=(const RawIppClient&) = delete;

  // Sends the bytes as they are: add "\r\n" yourself, or use sendLine.
  void sendRaw(const std::string& bytes) {
    if (::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(bytes.size())) {
      throw std::runtime_error("send failed");
    }
  }
  void sendLine(const std::string& line) { sendRaw(line + "\r\n"); }

  // The next line without its CR LF, or nothing within `limit` (or at end of file).
  std::optional<std::string> readLine(std::chrono::milliseconds limit = 3000ms) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    for (;;) {
      if (const std::size_t end = buffer_.find("\r\n"); end != std::string::npos) {
        std::string line = buffer_.substr(0, end);
        buffer_.erase(0, end + 2);
        return line;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) return std::nullopt;
      std::array<char, 1024> chunk{};
      const ssize_t n = ::recv(fd_, chunk.data(), chunk.size(), 0);
      if (n <= 0) return std::nullopt;
      buffer_.append(chunk.data(), static_cast<std::size_t>(n));
    }
  }

  // Every line up to and including `last`; stops early (and the test fails) on a timeout.
  std::vector<std::string> readThrough(const std::string& last, std::chrono::milliseconds limit = 3000ms) {
    std::vector<std::string> lines;
    while (std::optional<std::string> line = readLine(limit)) {
      lines.push_back(*line);
      if (*line == last) break;
    }
    return lines;
  }

  // Sends `TAG command` and returns its response lines through `TAG %`.
  std::vector<std::string> transact(const std::string& tag, const std::string& command) {
    sendLine(tag + " " + command);
    return readThrough(tag + " %");
  }

 private:
  int fd_ = -1;
  std::string buffer_;
};

// Collects move reports from the driver's reader thread.
class ReportLog {
 public:
  drivers::cmm::MoveReportCallback callback() {
    return [this](const drivers::cmm::MoveReport& r) {
      {
        std::lock_guard lock(mutex_);
        reports_.push_back(r);
      }
      changed_.notify_all();
    };
  }
  std::vector<drivers::cmm::MoveReport> reports() const {
    std::lock_guard lock(mutex_);
    return reports_;
  }
  // The reports once the last one satisfies `at_target`: a move's `%` comes when the machine
  // arrives, and the report at its target may follow within the daemon's rate limit (0.1 s).
  std::vector<drivers::cmm::MoveReport> reportsEndingWith(const std::function<bool(const drivers::cmm::MoveReport&)>& at_target,
                                                          std::chrono::milliseconds limit = 1000ms) {
    std::unique_lock lock(mutex_);
    changed_.wait_for(lock, limit, [&] { return !reports_.empty() && at_target(reports_.back()); });
    return reports_;
  }
  void clear() {
    std::lock_guard lock(mutex_);
    reports_.clear();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<drivers::cmm::MoveReport> reports_;
};

}  // namespace stampscan::test
