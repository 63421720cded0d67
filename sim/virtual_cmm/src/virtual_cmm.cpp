// The virtual CMM's TCP side: listen, serve one connection at a time (§9.2, §9.3), frame lines, and
// the fault injection hooks. What the lines mean is IppSession's business.
#include "stampscan/sim/virtual_cmm.hpp"

#include "cmm_machine.hpp"
#include "ipp_session.hpp"

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <thread>

namespace stampscan::sim {

namespace ipp = drivers::cmm::ipp;

struct VirtualCmm::Impl {
  explicit Impl(VirtualCmmConfig config) : machine(std::move(config)) {}

  void run();
  void serve(int fd);
  bool waitReadable(int fd);  // false when stop() was called

  detail::CmmMachine machine;
  detail::FaultInjection faults;
  std::atomic<bool> silent{false};

  mutable std::mutex mutex;
  int listen_fd = -1;
  int wake_fd = -1;  // an eventfd that stop() makes readable, waking every poll()
  std::uint16_t port = 0;
  int connection_fd = -1;
  std::size_t connections = 0;
  const detail::IppSession* active_session = nullptr;  // while a connection is served, for status()
  std::thread thread;
};

namespace {
std::string errnoText() { return std::strerror(errno); }
}  // namespace

VirtualCmm::VirtualCmm(VirtualCmmConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}

VirtualCmm::~VirtualCmm() { stop(); }

const VirtualCmmConfig& VirtualCmm::config() const { return impl_->machine.config(); }

std::uint16_t VirtualCmm::port() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->port;
}

void VirtualCmm::start() {
  Impl& m = *impl_;
  std::lock_guard lock(m.mutex);
  if (m.thread.joinable()) throw std::logic_error("virtual CMM started twice");
  const VirtualCmmConfig& c = m.machine.config();
  const std::string where = c.address + ":" + std::to_string(c.port);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICHOST | AI_PASSIVE;
  addrinfo* found = nullptr;
  if (const int rc = ::getaddrinfo(c.address.c_str(), std::to_string(c.port).c_str(), &hints, &found); rc != 0) {
    throw std::runtime_error("virtual CMM: bad address " + where + ": " + ::gai_strerror(rc));
  }
  const int fd = ::socket(found->ai_family, found->ai_socktype | SOCK_CLOEXEC, found->ai_protocol);
  const int on = 1;
  // Reuse a port another test left in TIME_WAIT.
  if (fd >= 0) ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof(on));
  if (fd < 0 || ::bind(fd, found->ai_addr, found->ai_addrlen) != 0 || ::listen(fd, 4) != 0) {
    const std::string why = errnoText();
    ::freeaddrinfo(found);
    if (fd >= 0) ::close(fd);
    throw std::runtime_error("virtual CMM: cannot listen on " + where + ": " + why);
  }
  ::freeaddrinfo(found);
  sockaddr_storage bound{};
  socklen_t length = sizeof(bound);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &length);
  m.port = ntohs(bound.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port
                                              : reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
  m.listen_fd = fd;
  m.wake_fd = ::eventfd(0, EFD_CLOEXEC);
  m.thread = std::thread([&m] { m.run(); });
}

void VirtualCmm::stop() {
  Impl& m = *impl_;
  {
    std::lock_guard lock(m.mutex);
    if (!m.thread.joinable()) return;
  }
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t written = ::write(m.wake_fd, &one, sizeof(one));
  m.thread.join();
  std::lock_guard lock(m.mutex);
  ::close(m.listen_fd);
  ::close(m.wake_fd);
  m.listen_fd = m.wake_fd = -1;
}

VirtualCmmStatus VirtualCmm::status() const { return statusAt(detail::Clock::now()); }

VirtualCmmStatus VirtualCmm::statusAt(std::chrono::steady_clock::time_point when) const {
  const Impl& m = *impl_;
  VirtualCmmStatus s;
  const detail::MachinePose pose = m.machine.pose(when);
  s.position = pose.xyz;
  constexpr double kRadPerDeg = std::numbers::pi / 180;  // the wire's degrees (§6.1.2) to the house's radians
  s.head_a = pose.abc[0] * kRadPerDeg;
  s.head_b = pose.abc[1] * kRadPerDeg;
  s.head_c = pose.abc[2] * kRadPerDeg;
  s.homed = m.machine.homed();
  s.moving = m.machine.moving();
  s.active_tool = m.machine.activeToolName();
  s.moves_completed = m.machine.movesCompleted();
  s.moves_aborted = m.machine.movesAborted();
  std::lock_guard lock(m.mutex);
  s.connected = m.connection_fd >= 0;
  s.connections_served = m.connections;
  if (m.active_session != nullptr) {
    s.session_active = m.active_session->sessionActive();
    s.error_state = m.active_session->errorState();
  }
  return s;
}

void VirtualCmm::failNextCommand(int error_number, std::optional<int> severity) {
  impl_->faults.failNext(error_number, severity);
}

void VirtualCmm::dropConnection() {
  std::lock_guard lock(impl_->mutex);
  // The serving thread sees end of file and closes; the client sees the connection go.
  if (impl_->connection_fd >= 0) ::shutdown(impl_->connection_fd, SHUT_RDWR);
}

void VirtualCmm::setSilent(bool silent) { impl_->silent = silent; }

bool VirtualCmm::Impl::waitReadable(int fd) {
  for (;;) {
    std::array<pollfd, 2> fds{{{fd, POLLIN, 0}, {wake_fd, POLLIN, 0}}};
    if (::poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    if (fds[1].revents != 0) return false;
    if (fds[0].revents != 0) return true;
  }
}

void VirtualCmm::Impl::run() {
  while (waitReadable(listen_fd)) {
    const int fd = ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd >= 0) serve(fd);  // the next client waits in the listen queue meanwhile (§9.3)
  }
}

void VirtualCmm::Impl::serve(int fd) {
  const int on = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof(on));
  timeval send_timeout{2, 0};  // a client that stops reading must not wedge the server
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &send_timeout, sizeof(send_timeout));
  {
    std::lock_guard lock(mutex);
    connection_fd = fd;
    ++connections;
  }
  std::mutex write_mutex;
  const auto sink = [this, fd, &write_mutex](const std::string& line) {
    if (silent) return;
    const std::string framed = ipp::frameLine(line);
    std::lock_guard lock(write_mutex);
    for (std::size_t sent = 0; sent < framed.size();) {
      const ssize_t n = ::send(fd, framed.data() + sent, framed.size() - sent, MSG_NOSIGNAL);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return;  // the reader sees the broken connection and ends the session
      sent += static_cast<std::size_t>(n);
    }
  };
  {
    detail::IppSession session(machine, faults, sink);
    {
      std::lock_guard lock(mutex);
      active_session = &session;
    }
    ipp::LineFramer framer;
    std::array<char, 4096> buffer{};
    while (waitReadable(fd)) {
      const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), 0);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      framer.append(std::string_view(buffer.data(), static_cast<std::size_t>(n)));
      while (std::optional<ipp::LineFramer::Line> line = framer.next()) session.onLine(*line);
    }
    std::lock_guard lock(mutex);
    active_session = nullptr;
  }  // ~IppSession stops a move in progress and the executor
  std::lock_guard lock(mutex);
  connection_fd = -1;
  ::close(fd);
}

}  // namespace stampscan::sim
