// The virtual CMM's TCP side: listen, serve one connection at a time (§9.2, §9.3) with an idle
// timeout, hold or refuse a second client, frame lines, send each whole or close, and the fault
// injection hooks. What the lines mean is IppSession's business.
#include "stampscan/sim/virtual_cmm.hpp"

#include "cmm_machine.hpp"
#include "ipp_session.hpp"
#include "stampscan/drivers/cmm/ipp_errors.hpp"

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <thread>
#include <utility>

namespace stampscan::sim {

namespace ipp = drivers::cmm::ipp;

struct VirtualCmm::Impl {
  explicit Impl(VirtualCmmConfig config) : machine(std::move(config)) {}

  void run();
  void serve(int fd);
  // accept4() on the listening socket; -1 when nothing was accepted. Out of descriptors it pauses
  // the listening socket for kAcceptBackoff rather than let poll() wake it again at once.
  int acceptOne();
  bool listenPaused() const { return detail::Clock::now() < listen_paused_until; }
  // Tells a second client why it is not served, then closes it.
  void refuse(int fd);
  // Sends one framed line whole before `deadline`; false when it could not (the caller closes).
  static bool sendWhole(int fd, const std::string& framed, detail::Clock::time_point deadline);

  detail::CmmMachine machine;
  detail::FaultInjection faults;
  std::atomic<bool> silent{false};

  mutable std::mutex mutex;
  int listen_fd = -1;
  int wake_fd = -1;  // an eventfd that stop() makes readable, waking every poll()
  std::uint16_t port = 0;
  int connection_fd = -1;
  std::size_t connections = 0;
  std::size_t refused = 0;
  std::size_t idle_disconnects = 0;
  std::size_t slow_reader_disconnects = 0;
  const detail::IppSession* active_session = nullptr;  // while a connection is served, for status()
  std::thread thread;

  // Serving thread only.
  int waiting_fd = -1;  // a second client, accepted while another is served
  detail::Clock::time_point waiting_deadline;
  detail::Clock::time_point listen_paused_until;
};

namespace {
std::string errnoText() { return std::strerror(errno); }

using detail::Clock;

// Out of descriptors (EMFILE, ENFILE) or kernel memory, accept() fails while the connection stays
// queued, so poll() reports the listening socket readable again at once: without a pause the loop
// would spin at full CPU until a descriptor is freed.
constexpr auto kAcceptBackoff = std::chrono::milliseconds(100);

bool outOfResources(int error) { return error == EMFILE || error == ENFILE || error == ENOBUFS || error == ENOMEM; }

// poll() timeout in milliseconds until `deadline`, rounded up so that the wake-up is not early;
// -1 (no timeout) for time_point::max().
int pollTimeout(Clock::time_point deadline) {
  if (deadline == Clock::time_point::max()) return -1;
  const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return static_cast<int>(std::clamp<long long>(left, 0, 60'000));
}
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
  if (m.waiting_fd >= 0) ::close(std::exchange(m.waiting_fd, -1));
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
  const detail::MachinePose destination = m.machine.destination(when);
  s.destination = destination.xyz;
  s.destination_a = destination.abc[0] * kRadPerDeg;
  s.destination_b = destination.abc[1] * kRadPerDeg;
  s.destination_c = destination.abc[2] * kRadPerDeg;
  s.homed = m.machine.homed();
  s.moving = m.machine.moving();
  s.active_tool = m.machine.activeToolName();
  s.moves_completed = m.machine.movesCompleted();
  s.moves_aborted = m.machine.movesAborted();
  std::lock_guard lock(m.mutex);
  s.connected = m.connection_fd >= 0;
  s.connections_served = m.connections;
  s.connections_refused = m.refused;
  s.idle_disconnects = m.idle_disconnects;
  s.slow_reader_disconnects = m.slow_reader_disconnects;
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

int VirtualCmm::Impl::acceptOne() {
  const int fd = ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
  if (fd < 0 && outOfResources(errno)) listen_paused_until = Clock::now() + kAcceptBackoff;
  return fd;  // other failures (a client that gave up meanwhile) need no pause
}

void VirtualCmm::Impl::run() {
  for (;;) {
    int fd = std::exchange(waiting_fd, -1);
    while (fd < 0) {
      // Only the wake-up descriptor while the listening socket is paused (acceptOne()).
      std::array<pollfd, 2> fds{{{wake_fd, POLLIN, 0}, {listen_fd, POLLIN, 0}}};
      const bool paused = listenPaused();
      if (::poll(fds.data(), paused ? 1 : 2, paused ? pollTimeout(listen_paused_until) : -1) < 0 && errno != EINTR) {
        return;
      }
      if (fds[0].revents != 0) return;  // stop()
      if (!paused && fds[1].revents != 0) fd = acceptOne();
    }
    serve(fd);
  }
}

void VirtualCmm::Impl::refuse(int fd) {
  {
    std::lock_guard lock(mutex);  // counted first: the client may look at status() once it is told
    ++refused;
  }
  // One line on a fresh socket fits its empty send buffer: MSG_DONTWAIT cannot cut it.
  const std::string line = ipp::frameLine(ipp::formatReply(ipp::Reply::errorLine(
      ipp::Tag::serverEvent(), ipp::makeError(ipp::error::kErrorProcessingMethod, "Connect"))));
  [[maybe_unused]] const ssize_t sent = ::send(fd, line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  // Read what the client sent meanwhile (a StartSession, typically): closing a socket with unread
  // data resets the connection, and a reset may discard the refusal before the client reads it.
  std::array<char, 4096> discard{};
  while (::recv(fd, discard.data(), discard.size(), MSG_DONTWAIT) > 0) {
  }
  ::close(fd);
}

bool VirtualCmm::Impl::sendWhole(int fd, const std::string& framed, Clock::time_point deadline) {
  for (std::size_t sent = 0; sent < framed.size();) {
    const ssize_t n = ::send(fd, framed.data() + sent, framed.size() - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) return false;  // the connection broke
    pollfd p{fd, POLLOUT, 0};
    const int timeout = pollTimeout(deadline);
    if (timeout == 0) return false;  // a client that reads this slowly is not served any more
    if (::poll(&p, 1, timeout) < 0 && errno != EINTR) return false;
  }
  return true;
}

void VirtualCmm::Impl::serve(int fd) {
  const int on = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof(on));
  {
    std::lock_guard lock(mutex);
    connection_fd = fd;
    ++connections;
  }
  const VirtualCmmConfig& config = machine.config();
  std::mutex write_mutex;
  bool broken = false;  // a line missed its deadline: nothing more is sent, the connection closes
  const auto sink = [this, fd, &write_mutex, &broken, &config](const std::string& line) {
    if (silent) return;
    const std::string framed = ipp::frameLine(line);
    std::lock_guard lock(write_mutex);
    if (broken) return;
    if (!sendWhole(fd, framed, Clock::now() + config.send_timeout)) {
      // Never a line cut short and run into the next one: at most this line's start, then the end
      // of the stream. The reader sees end of file and ends the session.
      broken = true;
      {
        std::lock_guard count(mutex);
        ++slow_reader_disconnects;
      }
      ::shutdown(fd, SHUT_RDWR);
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
    Clock::time_point last_received = Clock::now();
    for (;;) {
      // Idle: nothing received and no command running since idle_from; a running command defers
      // the check (the session's idleSince() restarts the count when it finishes).
      const std::optional<Clock::time_point> done = session.idleSince();
      const Clock::time_point now = Clock::now();
      const Clock::time_point idle_deadline =
          done ? std::max(last_received, *done) + config.idle_timeout : now + config.idle_timeout;
      if (done && now >= idle_deadline) {
        std::lock_guard lock(mutex);
        ++idle_disconnects;
        break;
      }
      if (waiting_fd >= 0 && now >= waiting_deadline) refuse(std::exchange(waiting_fd, -1));
      Clock::time_point wake = idle_deadline;
      if (waiting_fd >= 0) wake = std::min(wake, waiting_deadline);
      const bool paused = listenPaused();
      if (paused) wake = std::min(wake, listen_paused_until);

      std::array<pollfd, 3> fds{{{fd, POLLIN, 0}, {wake_fd, POLLIN, 0}, {listen_fd, POLLIN, 0}}};
      if (::poll(fds.data(), paused ? 2 : 3, pollTimeout(wake)) < 0) {
        if (errno == EINTR) continue;
        break;
      }
      if (fds[1].revents != 0) break;  // stop()
      if (!paused && fds[2].revents != 0) {
        if (const int next = acceptOne(); next >= 0) {
          if (waiting_fd >= 0) {
            refuse(next);  // one client waits at most; more would only wait to be refused
          } else {
            waiting_fd = next;
            waiting_deadline = Clock::now() + config.second_client_wait;
          }
        }
      }
      if (fds[0].revents == 0) continue;
      const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), 0);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      last_received = Clock::now();
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
