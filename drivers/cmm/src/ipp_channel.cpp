#include "ipp_channel.hpp"

#include "stampscan/drivers/cmm/ipp_errors.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace stampscan::drivers::cmm::detail {

namespace {

std::string errnoText(int error) { return std::strerror(error); }

// A connected, blocking TCP socket, or an exception naming the address and the reason. The connect
// itself is non-blocking so that an unreachable controller costs `timeout`, not the kernel's minutes.
int connectSocket(const std::string& host, std::uint16_t port, std::chrono::milliseconds timeout) {
  const std::string where = host + ":" + std::to_string(port);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  if (const int rc = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found); rc != 0) {
    throw std::runtime_error(where + ": cannot resolve: " + ::gai_strerror(rc));
  }
  std::string failure = "no address";
  int fd = -1;
  for (addrinfo* a = found; a != nullptr && fd < 0; a = a->ai_next) {
    const int s = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if (s < 0) {
      failure = errnoText(errno);
      continue;
    }
    const int flags = ::fcntl(s, F_GETFL, 0);
    ::fcntl(s, F_SETFL, flags | O_NONBLOCK);
    int error = 0;
    if (::connect(s, a->ai_addr, a->ai_addrlen) != 0) {
      error = errno;
      if (error == EINPROGRESS) {
        pollfd p{s, POLLOUT, 0};
        const int ready = ::poll(&p, 1, static_cast<int>(timeout.count()));
        if (ready == 0) {
          error = ETIMEDOUT;
        } else if (ready < 0) {
          error = errno;
        } else {
          socklen_t length = sizeof(error);
          ::getsockopt(s, SOL_SOCKET, SO_ERROR, &error, &length);
        }
      }
    }
    if (error != 0) {
      failure = error == ETIMEDOUT ? "the CMM does not answer (no connection within " + std::to_string(timeout.count()) + " ms)"
                                   : errnoText(error);
      ::close(s);
      continue;
    }
    ::fcntl(s, F_SETFL, flags);  // blocking for the reader; writeAll() sends with MSG_DONTWAIT
    const int on = 1;  // lines are short and each waits for an answer: no Nagle delay
    ::setsockopt(s, IPPROTO_TCP, TCP_NODELAY, &on, sizeof(on));
    fd = s;
  }
  ::freeaddrinfo(found);
  if (fd < 0) throw std::runtime_error("cannot connect to the CMM at " + where + ": " + failure);
  return fd;
}

}  // namespace

IppChannel::IppChannel(const std::string& host, std::uint16_t port, std::chrono::milliseconds connect_timeout,
                       std::chrono::milliseconds ack_wait, Callbacks callbacks)
    : fd_(connectSocket(host, port, connect_timeout)), ack_wait_(ack_wait), callbacks_(std::move(callbacks)) {
  reader_ = std::thread([this] { readLoop(); });
}

IppChannel::~IppChannel() { close(); }

void IppChannel::close() noexcept {
  {
    std::lock_guard lock(mutex_);
    if (closing_) return;
    closing_ = true;
  }
  ::shutdown(fd_, SHUT_RDWR);  // wakes the reader's recv()
  if (reader_.joinable()) reader_.join();
  ::close(fd_);
  std::lock_guard lock(mutex_);
  lost_ = true;
  if (lost_reason_.empty()) lost_reason_ = "closed";
  changed_.notify_all();
}

bool IppChannel::lost() const {
  std::lock_guard lock(mutex_);
  return lost_;
}

std::string IppChannel::lostReason() const {
  std::lock_guard lock(mutex_);
  return lost_reason_;
}

std::uint64_t IppChannel::linesDropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

ipp::Tag IppChannel::allocateTag(bool event) {
  // Tags count up and wrap; one still in use (a slow transaction, a running daemon) is skipped, so
  // tags stay unique while the server processes them (§6.2.1).
  int& next = event ? next_event_ : next_command_;
  const int last = event ? 9999 : 99999;
  for (int tries = 0; tries < last; ++tries) {
    const ipp::Tag tag = event ? ipp::Tag::event(next) : ipp::Tag::command(next);
    next = next == last ? 1 : next + 1;
    if (pending_.count(tag) == 0 && daemons_.count(tag) == 0) return tag;
  }
  throw std::runtime_error("all I++ DME tags are in use");
}

bool IppChannel::writeAll(const std::string& bytes) {
  // One deadline for the whole line: a server that stops reading, or reads a byte at a time, must not
  // hold a sender for ever (a per-call SO_SNDTIMEO would restart with every byte taken).
  const auto deadline = std::chrono::steady_clock::now() + ack_wait_;
  std::size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n == 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) return false;
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd p{fd_, POLLOUT, 0};
    if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) == 0) {
      errno = ETIMEDOUT;
      return false;
    }
  }
  return true;
}

std::shared_ptr<Transaction> IppChannel::send(const std::string& name, std::vector<ipp::Argument> args, bool event,
                                              LineHandler daemon) {
  std::lock_guard send_lock(send_mutex_);
  auto transaction = std::make_shared<Transaction>();
  {
    std::unique_lock lock(mutex_);
    // §6.2.3: a new transaction only after the Ack of the previous one. Bounded: a server that never
    // acks makes the caller's own wait time out instead.
    changed_.wait_for(lock, ack_wait_, [&] {
      if (lost_) return true;
      for (const auto& [tag, t] : pending_) {
        if (!t->acked) return false;
      }
      return true;
    });
    transaction->tag = allocateTag(event);
    transaction->line = ipp::formatCommand({transaction->tag, name, std::move(args)});
    if (lost_) return transaction;  // wait() reports Lost
    pending_[transaction->tag] = transaction;
    if (daemon) daemons_[transaction->tag] = std::move(daemon);
  }
  if (!writeAll(ipp::frameLine(transaction->line))) {
    markLost(errno == ETIMEDOUT ? "the CMM took no command for " + std::to_string(ack_wait_.count()) + " ms"
                                : "cannot send to the CMM: " + errnoText(errno));
  }
  return transaction;
}

WaitResult IppChannel::wait(const Transaction& transaction, std::chrono::steady_clock::time_point deadline) {
  std::unique_lock lock(mutex_);
  const bool done = changed_.wait_until(lock, deadline, [&] { return transaction.complete || lost_; });
  if (transaction.complete) return WaitResult::Complete;
  if (!done) {
    pending_.erase(transaction.tag);
    daemons_.erase(transaction.tag);
    return WaitResult::Timeout;
  }
  return WaitResult::Lost;
}

void IppChannel::removeDaemon(ipp::Tag tag) {
  std::lock_guard lock(mutex_);
  daemons_.erase(tag);
}

void IppChannel::markLost(const std::string& why) {
  std::function<void(const std::string&)> report;
  {
    std::lock_guard lock(mutex_);
    if (lost_ || losing_) return;
    losing_ = true;
    if (!closing_) report = callbacks_.lost;
  }
  // Report first, then wake the waiters: whoever sees the call fail also sees the fault recorded.
  if (report) report(why);
  std::lock_guard lock(mutex_);
  lost_ = true;
  lost_reason_ = why;
  pending_.clear();
  daemons_.clear();
  changed_.notify_all();
}

void IppChannel::readLoop() {
  ipp::LineFramer framer;
  std::array<char, 4096> buffer{};
  for (;;) {
    const ssize_t n = ::recv(fd_, buffer.data(), buffer.size(), 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      std::string why = n == 0 ? "the CMM closed the connection" : "connection to the CMM failed: " + errnoText(errno);
      {
        // A server that refuses or drops a client says why on E0000 just before (§6.2.4.1).
        std::lock_guard lock(mutex_);
        if (!last_server_error_.empty()) why += " after reporting " + last_server_error_;
      }
      markLost(why);
      return;
    }
    framer.append(std::string_view(buffer.data(), static_cast<std::size_t>(n)));
    while (std::optional<ipp::LineFramer::Line> line = framer.next()) {
      try {
        if (line->problem == ipp::LineFramer::Problem::TooLong) {
          throw ipp::ProtocolError(ipp::error::kProtocolError, ipp::kMaxLineLength, "line too long", line->text);
        }
        dispatch(ipp::parseReply(line->text));
      } catch (const ipp::ProtocolError& e) {
        if (callbacks_.garbled) callbacks_.garbled(std::string("unreadable response: ") + e.what());
      }
    }
  }
}

void IppChannel::dispatch(const ipp::Reply& reply) {
  LineHandler handler;
  {
    std::lock_guard lock(mutex_);
    const auto daemon = daemons_.find(reply.tag);
    if (daemon != daemons_.end() && reply.kind == ipp::ReplyKind::Data) {
      handler = daemon->second;  // §6.2.4: daemon data may come before or after its `%`
    } else if (const auto it = pending_.find(reply.tag); it != pending_.end()) {
      Transaction& t = *it->second;
      switch (reply.kind) {
        case ipp::ReplyKind::Ack: t.acked = true; break;
        case ipp::ReplyKind::Data: t.data.push_back(reply.data); break;
        case ipp::ReplyKind::Error: t.errors.push_back(reply.error); break;
        case ipp::ReplyKind::Complete:
          t.acked = true;
          t.complete = true;
          pending_.erase(it);
          break;
      }
      changed_.notify_all();
    } else if (reply.tag.isServerEvent()) {
      handler = callbacks_.unsolicited;
      if (reply.kind == ipp::ReplyKind::Error) last_server_error_ = ipp::describe(reply.error);
    } else {
      ++dropped_;  // the answer to a transaction that timed out, or a stopped daemon's last report
    }
  }
  if (handler) handler(reply);
}

}  // namespace stampscan::drivers::cmm::detail
