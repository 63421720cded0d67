// The PLC driver and the virtual PLC against hostile or broken peers: a device that dribbles its
// reply, one that never accepts, idle and excess connections, foreign unit and protocol ids, and a
// process out of file descriptors. Time bounds are generous (3x the deadline): the suite must not
// be flaky on a loaded machine.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "hostile_peer_support.hpp"
#include "plc_test_support.hpp"

namespace stampscan::plc_test {
namespace {

using drivers::DeviceError;
using Bytes = std::vector<std::uint8_t>;

using test::listenOnLoopback;

sockaddr_in loopback(int port) { return test::loopbackAddress(port); }

// A Modbus TCP client on raw bytes, to send what the driver never would.
class RawModbusClient {
 public:
  // Connects unless `fd` is given: an unconnected socket made earlier, connected here.
  explicit RawModbusClient(int port, int fd = -1) : fd_(fd >= 0 ? fd : ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)) {
    const sockaddr_in address = loopback(port);
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
      ::close(fd_);
      throw std::runtime_error("cannot connect to the virtual PLC");
    }
  }
  ~RawModbusClient() { ::close(fd_); }
  RawModbusClient(const RawModbusClient&) = delete;
  RawModbusClient& operator=(const RawModbusClient&) = delete;

  void send(const Bytes& bytes) {
    if (::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(bytes.size()))
      throw std::runtime_error("send to the virtual PLC failed");
  }

  // One response ADU, or nothing within `limit` or at the end of the stream.
  std::optional<Bytes> readAdu(std::chrono::milliseconds limit = 2000ms) {
    const Clock::time_point deadline = Clock::now() + limit;
    for (;;) {
      if (buffer_.size() >= 7) {
        const std::size_t size = 6 + static_cast<std::size_t>((buffer_[4] << 8) | buffer_[5]);
        if (buffer_.size() >= size) {
          Bytes adu(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(size));
          buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(size));
          return adu;
        }
      }
      if (!fill(deadline)) return std::nullopt;
    }
  }

  // True when the server closes the connection within `limit`.
  bool closedWithin(std::chrono::milliseconds limit) {
    const Clock::time_point deadline = Clock::now() + limit;
    while (fill(deadline)) {
    }
    return closed_;
  }

 private:
  // Reads what arrives before `deadline`; false at the deadline or the end of the stream.
  bool fill(Clock::time_point deadline) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    pollfd p{fd_, POLLIN, 0};
    if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) return false;
    std::array<std::uint8_t, 512> chunk{};
    const ssize_t n = ::recv(fd_, chunk.data(), chunk.size(), 0);
    if (n <= 0) {
      closed_ = true;
      return false;
    }
    buffer_.insert(buffer_.end(), chunk.begin(), chunk.begin() + n);
    return true;
  }

  int fd_;
  Bytes buffer_;
  bool closed_ = false;
};

// Read input registers 0..`count`-1 (function 0x04) of `unit`, protocol id `protocol`.
Bytes readInputRegisters(std::uint8_t unit, std::uint16_t transaction = 1, std::uint8_t count = 6,
                         std::uint16_t protocol = 0) {
  return {static_cast<std::uint8_t>(transaction >> 8), static_cast<std::uint8_t>(transaction),
          static_cast<std::uint8_t>(protocol >> 8), static_cast<std::uint8_t>(protocol), 0, 6, unit, 0x04, 0, 0, 0, count};
}

// A fake Modbus server that answers every request correctly but one byte every `gap`: libmodbus's
// per-byte timeout never fires, only a whole-request deadline can.
class DribblingModbusServer {
 public:
  explicit DribblingModbusServer(std::chrono::milliseconds gap) : listen_fd_(listenOnLoopback(4, port_)) {
    thread_ = std::thread([this, gap] { run(gap); });
  }
  ~DribblingModbusServer() {
    stop_ = true;
    ::shutdown(listen_fd_, SHUT_RDWR);  // wakes accept()
    thread_.join();
    ::close(listen_fd_);
  }
  int port() const { return port_; }

 private:
  void run(std::chrono::milliseconds gap) {
    while (!stop_) {
      const int fd = ::accept(listen_fd_, nullptr, nullptr);
      if (fd < 0) return;
      std::array<std::uint8_t, 260> request{};
      while (!stop_ && ::recv(fd, request.data(), 12, MSG_WAITALL) == 12) {
        // A correct reply to a read (functions 1-4), dribbled.
        const std::uint16_t count = static_cast<std::uint16_t>((request[10] << 8) | request[11]);
        const std::size_t data = request[7] <= 2 ? (count + 7U) / 8U : 2U * count;
        Bytes reply{request[0], request[1], 0, 0, 0, static_cast<std::uint8_t>(3 + data), request[6], request[7],
                    static_cast<std::uint8_t>(data)};
        reply.resize(reply.size() + data, 0);
        for (std::size_t i = 0; i < reply.size() && !stop_; ++i) {
          if (::send(fd, &reply[i], 1, MSG_NOSIGNAL) != 1) break;
          std::this_thread::sleep_for(gap);
        }
      }
      ::close(fd);
    }
  }

  int port_ = 0;
  int listen_fd_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST(PlcDeadline, ADribbledReplyEndsAtTheRequestDeadline) {
  DribblingModbusServer server(150ms);  // a 10-byte reply would take 1.5 s
  ModbusPlcOptions opts = driverOptions(server.port());
  opts.watchdog = false;
  opts.response_timeout = 300ms;
  ModbusPlc driver(opts);
  const Clock::time_point start = Clock::now();
  try {
    driver.connect();  // identifying the PLC reads its inputs
    FAIL() << "a reply dribbled over seconds was accepted";
  } catch (const DeviceError& error) {
    const std::string what = error.what();
    EXPECT_EQ(error.code(), "timeout") << what;
    EXPECT_NE(what.find("127.0.0.1:" + std::to_string(server.port())), std::string::npos) << what;
    EXPECT_NE(what.find("no complete reply within 300 ms"), std::string::npos) << what;
  }
  EXPECT_LT(Clock::now() - start, 3 * opts.response_timeout) << "the request outlived its deadline";
}

TEST(PlcDeadline, APlcThatNeverAcceptsIsAClearTimeout) {
  const test::UnansweredPort unanswered;
  const int port = unanswered.port();
  ModbusPlcOptions opts = driverOptions(port);
  opts.connect_timeout = 300ms;
  ModbusPlc driver(opts);
  const Clock::time_point start = Clock::now();
  try {
    driver.connect();
    FAIL() << "connected to a queue that is never served";
  } catch (const DeviceError& error) {
    const std::string what = error.what();
    EXPECT_EQ(error.code(), "timeout") << what;
    EXPECT_NE(what.find("PLC at 127.0.0.1:" + std::to_string(port) + " does not answer (no connection within 300 ms)"),
              std::string::npos)
        << what;
    EXPECT_EQ(what.find("in progress"), std::string::npos) << what;
  }
  EXPECT_LT(Clock::now() - start, 3 * opts.connect_timeout);
}

TEST(VirtualPlcConnections, IdleConnectionsAreClosed) {
  sim::VirtualPlcOptions options = virtualPlcOptions();
  options.idle_timeout = 300ms;
  VirtualPlc plc(options);
  plc.start();
  RawModbusClient idle(plc.port());
  RawModbusClient busy(plc.port());
  const Clock::time_point start = Clock::now();
  bool busy_served = true;
  for (std::uint16_t t = 1; Clock::now() - start < 600ms; ++t) {  // twice the idle timeout
    busy.send(readInputRegisters(1, t));
    busy_served = busy_served && busy.readAdu().has_value();
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_TRUE(busy_served) << "a connection in use was closed";
  EXPECT_TRUE(idle.closedWithin(3 * options.idle_timeout)) << "the idle connection was kept";
  EXPECT_TRUE(waitUntil([&] { return plc.connectionCount() == 1; })) << plc.connectionCount();
}

TEST(VirtualPlcConnections, ARequestMustArriveWhole) {
  sim::VirtualPlcOptions options = virtualPlcOptions();
  options.request_timeout = 200ms;
  VirtualPlc plc(options);
  plc.start();
  RawModbusClient dribbler(plc.port());
  const Bytes request = readInputRegisters(1);
  const Clock::time_point start = Clock::now();
  bool closed = false;
  for (const std::uint8_t byte : request) {  // one byte every 100 ms: 1.2 s for the request
    try {
      dribbler.send({byte});
    } catch (const std::runtime_error&) {
      closed = true;
      break;
    }
    if (dribbler.closedWithin(100ms)) {
      closed = true;
      break;
    }
  }
  EXPECT_TRUE(closed) << "a request dribbled over a second was waited for";
  EXPECT_LT(Clock::now() - start, 3 * options.request_timeout);
}

TEST(VirtualPlcConnections, ConnectionsBeyondTheCapAreRefusedAtOnce) {
  sim::VirtualPlcOptions options = virtualPlcOptions();
  options.max_connections = 2;
  VirtualPlc plc(options);
  plc.start();
  RawModbusClient first(plc.port());
  auto second = std::make_unique<RawModbusClient>(plc.port());
  ASSERT_TRUE(waitUntil([&] { return plc.connectionCount() == 2; }));
  RawModbusClient third(plc.port());
  EXPECT_TRUE(third.closedWithin(1000ms)) << "the connection over the cap was not closed";
  // The acceptor counts the refusal as it closes the connection: the count may trail the close.
  EXPECT_TRUE(waitUntil([&] { return plc.connectionsRefused() == 1U; })) << plc.connectionsRefused();
  first.send(readInputRegisters(1));
  EXPECT_TRUE(first.readAdu().has_value()) << "the connections within the cap are still served";

  // A place that is freed is taken again.
  second.reset();
  ASSERT_TRUE(waitUntil([&] { return plc.connectionCount() == 1; }));
  RawModbusClient fourth(plc.port());
  fourth.send(readInputRegisters(1));
  EXPECT_TRUE(fourth.readAdu().has_value());
}

TEST(VirtualPlcUnits, AnswersItsOwnUnitAndTheDeviceItselfOnly) {
  sim::VirtualPlcOptions options = virtualPlcOptions();
  options.unit_id = 3;
  VirtualPlc plc(options);
  plc.start();
  RawModbusClient client(plc.port());

  client.send(readInputRegisters(3, 0x0101));
  const std::optional<Bytes> own = client.readAdu();
  ASSERT_TRUE(own.has_value());
  EXPECT_EQ(own->size(), 9U + 12U) << "six registers";
  EXPECT_EQ((*own)[0], 0x01);
  EXPECT_EQ((*own)[7], 0x04);

  client.send(readInputRegisters(0xFF, 0x0102));
  const std::optional<Bytes> itself = client.readAdu();
  ASSERT_TRUE(itself.has_value()) << "0xFF addresses the TCP device itself";
  EXPECT_EQ((*itself)[7], 0x04);

  for (const std::uint8_t other : {std::uint8_t{1}, std::uint8_t{0}, std::uint8_t{7}}) {
    client.send(readInputRegisters(other, 0x0200 + other));
    const std::optional<Bytes> refused = client.readAdu();
    ASSERT_TRUE(refused.has_value()) << "unit " << int{other};
    EXPECT_EQ(*refused, (Bytes{0x02, other, 0, 0, 0, 3, other, 0x84, 0x0B})) << "unit " << int{other};
  }

  // Protocol id 1 is not Modbus: no answer, and the connection stays usable.
  client.send(readInputRegisters(3, 0x0301, 6, 1));
  EXPECT_FALSE(client.readAdu(300ms).has_value()) << "a frame of another protocol was answered";
  client.send(readInputRegisters(3, 0x0302));
  const std::optional<Bytes> after = client.readAdu();
  ASSERT_TRUE(after.has_value());
  EXPECT_EQ((*after)[1], 0x02);

  // The driver with a wrong unit id learns so at once, not by a timeout.
  ModbusPlcOptions opts = driverOptions(plc.port());
  opts.watchdog = false;
  opts.unit_id = 5;
  ModbusPlc driver(opts);
  try {
    driver.connect();  // identifying the PLC reads its inputs
    FAIL() << "a request for unit 5 was answered by unit 3";
  } catch (const DeviceError& error) {
    EXPECT_EQ(error.code(), "protocol") << error.what();
    EXPECT_NE(std::string(error.what()).find("unit 5"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("Target device failed to respond"), std::string::npos) << error.what();
  }
}

TEST(VirtualPlcUnits, ServesTheDriverWithTheCellsUnitId) {
  VirtualPlc plc(virtualPlcOptions());
  plc.start();
  ModbusPlcOptions opts = driverOptions(plc.port());
  ASSERT_EQ(opts.unit_id, int{plc.options().unit_id}) << "driver and virtual PLC disagree on the default unit";
  opts.watchdog = false;
  ModbusPlc driver(opts);
  driver.connect();
  EXPECT_TRUE(driver.readInputs().door_closed);
}

TEST(VirtualPlcConnections, AcceptLoopBacksOffWhenOutOfDescriptors) {
  VirtualPlc plc(virtualPlcOptions());
  plc.start();
  // The client's socket is made first: once descriptors run out, only connect() is left to do.
  const int client_fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(client_fd, 0);
  test::DescriptorExhaustion exhaustion;
  ASSERT_GT(exhaustion.held(), 0U);
  RawModbusClient client(plc.port(), client_fd);  // queued by the kernel; accept() fails with EMFILE

  const auto cpu_before = test::processCpuTime();
  std::this_thread::sleep_for(1s);
  const auto cpu_used = test::processCpuTime() - cpu_before;
  EXPECT_LT(cpu_used, 300ms) << "the accept loop spins while out of descriptors";

  exhaustion.release();
  client.send(readInputRegisters(1));
  EXPECT_TRUE(client.readAdu(2000ms).has_value()) << "the queued client was not served once descriptors were free";
}

}  // namespace
}  // namespace stampscan::plc_test
