#include "stampscan/sim/virtual_plc.hpp"

#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <list>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <thread>
#include <vector>

#include <modbus.h>

#include "modbus_frame.hpp"
#include "plc_logic.hpp"

namespace stampscan::sim {

using namespace drivers::plc;
using Clock = std::chrono::steady_clock;

namespace {

struct Connection {
  int fd;  // -1 once closed; guarded by Impl::connections_mutex
  std::thread thread;
  bool finished = false;
};

}  // namespace

struct VirtualPlc::Impl {
  explicit Impl(const VirtualPlcOptions& options) : image(detail::RegisterImage::allocate(options.registers)) {
    if (image == nullptr) throw std::runtime_error("virtual PLC: cannot allocate the register image");
    logic.emplace(detail::RegisterImage(*image, options.registers), options, Clock::now());
  }
  ~Impl() { modbus_mapping_free(image); }

  mutable std::mutex image_mutex;  // the image and the logic
  modbus_mapping_t* image;
  std::optional<detail::PlcLogic> logic;

  std::atomic<bool> silent{false};
  std::atomic<std::int64_t> reply_delay_ms{0};
  std::atomic<std::uint64_t> requests_answered{0};
  std::atomic<std::uint64_t> connections_refused{0};

  mutable std::mutex lifecycle_mutex;  // start/stop, running, port
  bool running = false;
  int port = 0;
  int listen_fd = -1;
  // A byte written here wakes every poll() at once: the stop signal of the socket threads.
  std::array<int, 2> wake_pipe{-1, -1};
  std::thread acceptor;
  std::thread cycler;

  std::mutex stop_mutex;  // `stopping` and the waits on it (logic cycle, reply delays)
  std::condition_variable stop_wake;
  bool stopping = false;

  mutable std::mutex connections_mutex;
  std::list<Connection> connections;  // a list: each thread holds a reference to its element

  bool waitForStop(Clock::duration duration) {
    std::unique_lock lock(stop_mutex);
    return stop_wake.wait_for(lock, duration, [&] { return stopping; });
  }

  // One signal's value, as a client would read it.
  template <class Signal>
  auto read(Signal signal) const {
    std::lock_guard lock(image_mutex);
    return logic->image().at(signal);
  }

  void acceptLoop(const VirtualPlcOptions& options);
  void serve(Connection& connection, const VirtualPlcOptions& options);
  // Answers one framed request; false when the connection must close.
  bool handle(modbus_t* context, int fd, const std::vector<std::uint8_t>& adu, const VirtualPlcOptions& options);
  std::size_t openConnections() const;
  void cycleLoop(std::chrono::milliseconds period);
  void reapFinished();
};

namespace {

// Out of descriptors (EMFILE, ENFILE) or kernel memory, accept() fails while the connection stays
// queued, so poll() reports the listening socket readable again at once: without a pause the loop
// would spin at full CPU until a descriptor is freed.
constexpr auto kAcceptBackoff = std::chrono::milliseconds(100);

bool outOfResources(int error) { return error == EMFILE || error == ENFILE || error == ENOBUFS || error == ENOMEM; }

// poll() timeout in milliseconds until `deadline`, rounded up so that the wake-up is not early.
int pollTimeout(Clock::time_point deadline) {
  const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return static_cast<int>(std::clamp<long long>(left, 0, 60'000));
}

// Waits until `fd` can take a reply; false when it cannot within `limit` or stop() came.
bool waitWritable(int fd, int wake_fd, std::chrono::milliseconds limit) {
  const Clock::time_point deadline = Clock::now() + limit;
  for (;;) {
    std::array<pollfd, 2> fds{{{fd, POLLOUT, 0}, {wake_fd, POLLIN, 0}}};
    const int ready = ::poll(fds.data(), fds.size(), pollTimeout(deadline));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0 || fds[1].revents != 0) return false;
    return (fds[0].revents & POLLOUT) != 0;
  }
}

}  // namespace

std::size_t VirtualPlc::Impl::openConnections() const {
  std::lock_guard lock(connections_mutex);
  std::size_t open = 0;
  for (const Connection& connection : connections) open += connection.finished ? 0 : 1;
  return open;
}

void VirtualPlc::Impl::acceptLoop(const VirtualPlcOptions& options) {
  Clock::time_point paused_until;
  for (;;) {
    // While paused (out of descriptors), only the stop signal is watched, with a timeout.
    const bool paused = Clock::now() < paused_until;
    std::array<pollfd, 2> fds{{{wake_pipe[0], POLLIN, 0}, {listen_fd, POLLIN, 0}}};
    if (::poll(fds.data(), paused ? 1 : 2, paused ? pollTimeout(paused_until) : -1) < 0) {
      if (errno == EINTR) continue;
      return;
    }
    if (fds[0].revents != 0) return;
    if (paused || fds[1].revents == 0) continue;
    const int fd = ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) {
      if (outOfResources(errno)) paused_until = Clock::now() + kAcceptBackoff;
      continue;  // otherwise the client gave up meanwhile: keep serving
    }
    reapFinished();
    if (openConnections() >= options.max_connections) {
      ::close(fd);  // refused at once: the client fails fast rather than waiting unserved
      ++connections_refused;
      continue;
    }
    // Replies are small single writes; without this, Nagle and delayed ACKs add up to 40 ms.
    const int on = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
    // A backstop for libmodbus's blocking send: handle() waits for room first (waitWritable).
    timeval send_limit{};
    send_limit.tv_sec = static_cast<time_t>(options.send_timeout.count() / 1000);
    send_limit.tv_usec = static_cast<suseconds_t>((options.send_timeout.count() % 1000) * 1000);
    ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &send_limit, sizeof send_limit);
    std::lock_guard lock(connections_mutex);
    Connection& connection = connections.emplace_back(Connection{fd, {}, false});
    connection.thread = std::thread([this, &connection, &options] { serve(connection, options); });
  }
}

bool VirtualPlc::Impl::handle(modbus_t* context, int fd, const std::vector<std::uint8_t>& adu,
                              const VirtualPlcOptions& options) {
  const detail::RequestVerdict verdict = detail::checkRequest(adu, options.unit_id);
  if (verdict.action == detail::RequestAction::Drop) return true;
  if (silent) return true;
  const std::chrono::milliseconds delay(reply_delay_ms.load());
  if (delay.count() > 0 && waitForStop(delay)) return false;
  // Room for the reply first, without the image's lock: a client that does not read its replies
  // must not hold up the other connections or the logic cycle.
  if (!waitWritable(fd, wake_pipe[0], options.send_timeout)) return false;
  if (verdict.action == detail::RequestAction::Refuse) {
    const std::vector<std::uint8_t> reply = detail::exceptionResponse(adu, verdict.exception_code);
    // A reply of 9 bytes into a writable socket goes out whole.
    if (::send(fd, reply.data(), reply.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(reply.size())) return false;
    ++requests_answered;
    return true;
  }
  std::lock_guard lock(image_mutex);
  const Clock::time_point now = Clock::now();
  logic->evaluate(now);  // the reply shows the state as of now (the watchdog may have expired)
  const int sent = modbus_reply(context, adu.data(), static_cast<int>(adu.size()), image);
  logic->evaluate(now);  // a write takes effect before anyone can read it back
  if (sent < 0) return false;
  ++requests_answered;
  return true;
}

void VirtualPlc::Impl::serve(Connection& connection, const VirtualPlcOptions& options) {
  // One libmodbus context per connection thread: contexts are not thread-safe. The context only
  // builds replies on the accepted socket; its address is never used to connect. Requests are read
  // and framed here rather than by modbus_receive(), which waits for the rest of a begun frame
  // without a limit and answers any unit id.
  modbus_t* context = modbus_new_tcp(options.address.c_str(), options.port);
  int fd = -1;
  {
    std::lock_guard lock(connections_mutex);
    fd = connection.fd;
  }
  if (context != nullptr) {
    modbus_set_socket(context, fd);
    // Before some exception replies modbus_reply() sleeps for the response timeout (to flush a
    // serial line), holding the register image: with the default 0.5 s, one bad request would stall
    // every connection. A microsecond keeps the behaviour without the stall.
    modbus_set_response_timeout(context, 0, 1);
    detail::ModbusTcpFramer framer;
    std::array<std::uint8_t, 1024> buffer{};
    Clock::time_point last_request = Clock::now();
    std::optional<Clock::time_point> partial_since;  // a request has begun but not ended
    bool open = true;
    while (open) {
      const Clock::time_point deadline =
          partial_since ? *partial_since + options.request_timeout : last_request + options.idle_timeout;
      std::array<pollfd, 2> fds{{{fd, POLLIN, 0}, {wake_pipe[0], POLLIN, 0}}};
      const int ready = ::poll(fds.data(), fds.size(), pollTimeout(deadline));
      if (ready < 0) {
        if (errno == EINTR) continue;
        break;
      }
      if (fds[1].revents != 0) break;
      if (ready == 0) {
        if (Clock::now() >= deadline) break;  // idle, or a request that never completed
        continue;
      }
      const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), 0);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;  // closed by the client or by dropConnections()
      framer.append(std::span<const std::uint8_t>(buffer.data(), static_cast<std::size_t>(n)));
      while (open) {
        const std::optional<std::vector<std::uint8_t>> adu = framer.next();
        if (!adu) break;
        last_request = Clock::now();
        partial_since.reset();
        open = handle(context, fd, *adu, options);
      }
      if (framer.broken()) break;  // a length no ADU can have: the stream cannot be framed any more
      if (framer.pendingBytes() == 0) {
        partial_since.reset();
      } else if (!partial_since) {
        partial_since = Clock::now();
      }
    }
    modbus_free(context);  // frees the context only; the socket is closed below
  }
  std::lock_guard lock(connections_mutex);
  ::close(connection.fd);
  connection.fd = -1;
  connection.finished = true;
}

void VirtualPlc::Impl::cycleLoop(std::chrono::milliseconds period) {
  Clock::time_point next = Clock::now();
  for (;;) {
    next += period;
    {
      std::unique_lock lock(stop_mutex);
      if (stop_wake.wait_until(lock, next, [&] { return stopping; })) return;
    }
    std::lock_guard lock(image_mutex);
    logic->cycle(Clock::now());
  }
}

void VirtualPlc::Impl::reapFinished() {
  std::vector<std::thread> done;
  {
    std::lock_guard lock(connections_mutex);
    for (auto it = connections.begin(); it != connections.end();) {
      if (it->finished) {
        done.push_back(std::move(it->thread));
        it = connections.erase(it);
      } else {
        ++it;
      }
    }
  }
  for (std::thread& thread : done) thread.join();
}

namespace {
const VirtualPlcOptions& validated(const VirtualPlcOptions& options) {
  if (const std::string problem = options.registers.problem(); !problem.empty())
    throw std::invalid_argument("virtual PLC: register map: " + problem);
  return options;
}
}  // namespace

VirtualPlc::VirtualPlc(VirtualPlcOptions options)
    : options_(validated(options)), impl_(std::make_unique<Impl>(options_)) {}

VirtualPlc::~VirtualPlc() { stop(); }

void VirtualPlc::start() {
  std::lock_guard lifecycle(impl_->lifecycle_mutex);
  if (impl_->running) return;
  const std::string where = options_.address + ":" + std::to_string(options_.port);
  modbus_t* listener = modbus_new_tcp(options_.address.c_str(), options_.port);
  if (listener == nullptr)
    throw std::runtime_error("virtual PLC: cannot create a Modbus context for " + where + ": " +
                             modbus_strerror(errno));
  const int fd = modbus_tcp_listen(listener, 8);
  const int listen_error = errno;
  modbus_free(listener);  // listening needs only the socket it returned
  if (fd < 0)
    throw std::runtime_error("virtual PLC: cannot listen on " + where + ": " +
                             std::strerror(listen_error));
  sockaddr_in bound{};
  socklen_t bound_size = sizeof bound;
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &bound_size) != 0 ||
      ::pipe2(impl_->wake_pipe.data(), O_CLOEXEC) != 0) {
    const int error = errno;
    ::close(fd);
    throw std::runtime_error("virtual PLC: cannot set up " + where + ": " + std::strerror(error));
  }
  impl_->listen_fd = fd;
  impl_->port = ntohs(bound.sin_port);
  {
    std::lock_guard lock(impl_->stop_mutex);
    impl_->stopping = false;
  }
  impl_->acceptor = std::thread([this] { impl_->acceptLoop(options_); });
  impl_->cycler = std::thread([this] { impl_->cycleLoop(options_.cycle); });
  impl_->running = true;
}

void VirtualPlc::stop() noexcept {
  std::lock_guard lifecycle(impl_->lifecycle_mutex);
  if (!impl_->running) return;
  {
    std::lock_guard lock(impl_->stop_mutex);
    impl_->stopping = true;
  }
  impl_->stop_wake.notify_all();
  const char wake = 's';
  [[maybe_unused]] const ssize_t written = ::write(impl_->wake_pipe[1], &wake, 1);
  impl_->acceptor.join();
  impl_->cycler.join();
  dropConnections();  // wakes a thread that is inside modbus_receive() mid-frame
  std::list<Connection> connections;
  {
    std::lock_guard lock(impl_->connections_mutex);
    connections.swap(impl_->connections);
  }
  for (Connection& connection : connections) connection.thread.join();
  ::close(impl_->listen_fd);
  ::close(impl_->wake_pipe[0]);
  ::close(impl_->wake_pipe[1]);
  impl_->listen_fd = -1;
  impl_->wake_pipe = {-1, -1};
  impl_->running = false;
}

bool VirtualPlc::running() const {
  std::lock_guard lifecycle(impl_->lifecycle_mutex);
  return impl_->running;
}

int VirtualPlc::port() const {
  std::lock_guard lifecycle(impl_->lifecycle_mutex);
  return impl_->port;
}

void VirtualPlc::setInput(DiscreteInput input, bool on) {
  std::lock_guard lock(impl_->image_mutex);
  impl_->logic->image().at(input) = on ? 1 : 0;
  impl_->logic->evaluate(Clock::now());
}

void VirtualPlc::requestStart(std::uint16_t program_number, std::string_view part_id) {
  const auto registers = drivers::plc::encodePartId(part_id);
  std::lock_guard lock(impl_->image_mutex);
  const detail::RegisterImage& image = impl_->logic->image();
  image.at(HoldingRegister::LineProgramNumber) = program_number;
  // line_part_id's registers follow its first one in the image (the map keeps them together).
  std::uint16_t* id = &image.at(HoldingRegister::LinePartId);
  for (std::size_t i = 0; i < registers.size(); ++i) id[i] = registers[i];
  image.at(HoldingRegister::LineStartRequest) = 1;
  impl_->logic->evaluate(Clock::now());
}

void VirtualPlc::dropStartRequest() {
  std::lock_guard lock(impl_->image_mutex);
  impl_->logic->image().at(HoldingRegister::LineStartRequest) = 0;
  impl_->logic->evaluate(Clock::now());
}

drivers::plc::CellAnswer VirtualPlc::cellAnswer() const {
  std::lock_guard lock(impl_->image_mutex);
  const detail::RegisterImage& image = impl_->logic->image();
  drivers::plc::CellAnswer a;
  a.ready = image.at(HoldingRegister::CellReady) != 0;
  a.busy = image.at(HoldingRegister::CellBusy) != 0;
  a.done = image.at(HoldingRegister::CellDone) != 0;
  a.verdict = static_cast<drivers::plc::LineVerdict>(image.at(HoldingRegister::CellVerdict));
  a.error = static_cast<drivers::plc::LineError>(image.at(HoldingRegister::CellErrorCode));
  return a;
}

bool VirtualPlc::input(DiscreteInput input) const { return impl_->read(input) != 0; }

bool VirtualPlc::coil(Coil coil) const { return impl_->read(coil) != 0; }

std::uint16_t VirtualPlc::holdingRegister(HoldingRegister reg) const { return impl_->read(reg); }

std::uint16_t VirtualPlc::inputRegister(InputRegister reg) const { return impl_->read(reg); }

bool VirtualPlc::interlockTripped() const {
  return inputRegister(InputRegister::InterlockState) != 0;
}

std::uint16_t VirtualPlc::faultWord() const { return inputRegister(InputRegister::FaultWord); }

std::uint64_t VirtualPlc::stationHeartbeatChanges() const {
  std::lock_guard lock(impl_->image_mutex);
  return impl_->logic->stationHeartbeatChanges();
}

void VirtualPlc::setSilent(bool silent) { impl_->silent = silent; }

void VirtualPlc::setReplyDelay(std::chrono::milliseconds delay) {
  impl_->reply_delay_ms = delay.count();
}

void VirtualPlc::dropConnections() {
  // shutdown() rather than close(): the serving thread sees end-of-file and closes the descriptor
  // itself, so no descriptor is closed twice or reused under a thread still reading it.
  std::lock_guard lock(impl_->connections_mutex);
  for (const Connection& connection : impl_->connections)
    if (connection.fd >= 0) ::shutdown(connection.fd, SHUT_RDWR);
}

std::size_t VirtualPlc::connectionCount() const { return impl_->openConnections(); }

std::uint64_t VirtualPlc::requestsAnswered() const { return impl_->requests_answered; }

std::uint64_t VirtualPlc::connectionsRefused() const { return impl_->connections_refused; }

}  // namespace stampscan::sim
