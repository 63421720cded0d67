// The virtual CMM and the CMM driver against hostile or broken peers: a client that reads slowly,
// an idle client and a second one, over-long responses, a process out of file descriptors, and for
// the driver a server that dribbles its answer or never accepts. Time bounds are generous (3x the
// deadline): the suite must not be flaky on a loaded machine.
#include "ipp_test_support.hpp"
#include "../plc/hostile_peer_support.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <thread>

namespace stampscan::sim {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using Lines = std::vector<std::string>;
namespace ipp = drivers::cmm::ipp;

VirtualCmmConfig configWith(std::chrono::milliseconds idle, std::chrono::milliseconds send,
                            std::chrono::milliseconds second_wait) {
  VirtualCmmConfig config = test::quickCmmConfig();
  config.idle_timeout = idle;
  config.send_timeout = send;
  config.second_client_wait = second_wait;
  return config;
}

// `GetProp(Tool.Name(), ...)` naming the property `count` times: 22 characters of response each.
std::string repeatedToolNames(std::size_t count) {
  std::string command = "GetProp(";
  for (std::size_t i = 0; i < count; ++i) command += i == 0 ? "Tool.Name()" : ", Tool.Name()";
  return command + ")";
}

TEST(VirtualCmmHardening, ASlowReaderGetsWholeLinesThenTheEnd) {
  VirtualCmm server(configWith(60s, 300ms, 2s));
  server.start();
  // A small receive window, so that the server's sends block soon.
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  const int window = 4096;
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &window, sizeof(window));
  const sockaddr_in address = test::loopbackAddress(server.port());
  ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)), 0);

  // 150 responses of 61 KB each (9 MB) and not a byte read for a second, from a thread: the server
  // stops taking commands too once its sends block.
  const std::string query = repeatedToolNames(2800);
  const std::string expected_data = ipp::formatArguments(
      std::vector<ipp::Argument>(2800, ipp::Argument::call("Tool.Name", {ipp::Argument::str("RefTool")})));
  std::thread sender([&] {
    std::string commands = "00001 StartSession()\r\n";
    for (int tag = 2; tag < 152; ++tag) commands += ipp::Tag::command(tag).str() + " " + query + "\r\n";
    for (std::size_t sent = 0; sent < commands.size();) {
      const ssize_t n = ::send(fd, commands.data() + sent, commands.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return;  // the server closed the connection
      sent += static_cast<std::size_t>(n);
    }
  });
  std::this_thread::sleep_for(1s);

  std::string received;
  const Clock::time_point deadline = Clock::now() + 10s;
  bool ended = false;
  while (!ended && Clock::now() < deadline) {
    std::array<char, 65536> chunk{};
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 500) <= 0) continue;
    const ssize_t n = ::recv(fd, chunk.data(), chunk.size(), 0);
    if (n <= 0) {
      ended = true;
    } else {
      received.append(chunk.data(), static_cast<std::size_t>(n));
    }
  }
  ::shutdown(fd, SHUT_RDWR);
  sender.join();
  ::close(fd);
  EXPECT_TRUE(ended) << "the server kept the connection of a client that does not read";
  EXPECT_EQ(server.status().slow_reader_disconnects, 1U);

  // Every line that arrived is whole: an Ack, a `%`, or the full data line. What follows the last
  // CR LF (at most the start of one line) is no line: the stream ended there.
  std::size_t lines = 0;
  for (std::size_t start = 0, end; (end = received.find("\r\n", start)) != std::string::npos; start = end + 2) {
    const std::string line = received.substr(start, end - start);
    ++lines;
    ASSERT_GE(line.size(), 7U) << "line " << lines;
    const std::string body = line.substr(6);
    EXPECT_TRUE(body == "&" || body == "%" || body == "# " + expected_data)
        << "line " << lines << " is cut or run together: " << line.substr(0, 80) << "..." << line.substr(line.size() - 80);
  }
  EXPECT_GT(lines, 2U);
  EXPECT_LT(lines, 3U * 151U) << "everything arrived: the client was never slow";

  // The machine is free for the next client.
  test::RawIppClient next(server.port());
  EXPECT_EQ(next.transact("00001", "StartSession()"), (Lines{"00001 &", "00001 %"}));
}

TEST(VirtualCmmHardening, AnIdleClientDoesNotBlockTheNext) {
  const auto idle = 300ms;
  VirtualCmm server(configWith(idle, 5s, 5s));
  server.start();
  test::RawIppClient first(server.port());
  ASSERT_EQ(first.transact("00001", "StartSession()"), (Lines{"00001 &", "00001 %"}));

  const Clock::time_point start = Clock::now();
  test::RawIppClient second(server.port());
  second.sendLine("00001 StartSession()");
  EXPECT_EQ(second.readThrough("00001 %", 3 * idle), (Lines{"00001 &", "00001 %"}));
  EXPECT_LT(Clock::now() - start, 3 * idle);
  EXPECT_EQ(first.readLine(100ms), std::nullopt) << "the idle client is disconnected";
  EXPECT_EQ(server.status().idle_disconnects, 1U);
}

TEST(VirtualCmmHardening, AMoveIsNotIdleness) {
  VirtualCmm server(configWith(200ms, 5s, 2s));
  server.start();
  test::RawIppClient client(server.port());
  ASSERT_EQ(client.transact("00001", "StartSession()"), (Lines{"00001 &", "00001 %"}));
  ASSERT_EQ(client.transact("00002", "Home()"), (Lines{"00002 &", "00002 %"}));
  ASSERT_EQ(client.transact("00003", "SetProp(Tool.GoToPar.Speed(200))"), (Lines{"00003 &", "00003 %"}));
  // 400 mm at 200 mm/s: two seconds without a byte from the client, ten idle timeouts.
  EXPECT_EQ(client.transact("00004", "GoTo(Z(100))"), (Lines{"00004 &", "00004 %"}));
  EXPECT_EQ(client.transact("00005", "Get(Z())"), (Lines{"00005 &", "00005 # Z(100)", "00005 %"}));
  EXPECT_EQ(server.status().idle_disconnects, 0U);
}

TEST(VirtualCmmHardening, ASecondClientIsRefusedClearlyWhileTheFirstWorks) {
  const auto wait = 300ms;
  VirtualCmm server(configWith(60s, 5s, wait));
  server.start();
  test::RawIppClient first(server.port());
  ASSERT_EQ(first.transact("00001", "StartSession()"), (Lines{"00001 &", "00001 %"}));

  const Clock::time_point start = Clock::now();
  test::RawIppClient second(server.port());
  second.sendLine("00001 StartSession()");
  EXPECT_EQ(second.readLine(3 * wait), "E0000 ! Error(3, 0511, \"Connect\", \"Error processing method\")");
  EXPECT_LT(Clock::now() - start, 3 * wait);
  EXPECT_EQ(second.readLine(1000ms), std::nullopt) << "the refused client is closed";
  EXPECT_EQ(server.status().connections_refused, 1U);
  EXPECT_EQ(first.transact("00002", "IsHomed()"), (Lines{"00002 &", "00002 # IsHomed(0)", "00002 %"}));

  // The driver, refused, says so.
  drivers::cmm::IppCmmOptions options;
  options.port = server.port();
  options.reply_timeout = 3000ms;
  drivers::cmm::IppCmm cmm(options);
  try {
    cmm.connect();
    FAIL() << "a second client was served";
  } catch (const drivers::DeviceError& error) {
    EXPECT_NE(std::string(error.what()).find("0511"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("Connect"), std::string::npos) << error.what();
  }
}

TEST(VirtualCmmHardening, EveryResponseStaysWithinTheLineLimit) {
  VirtualCmm server(test::quickCmmConfig());
  server.start();
  test::RawIppClient client(server.port());
  ASSERT_EQ(client.transact("00001", "StartSession()"), (Lines{"00001 &", "00001 %"}));
  const auto within = [](const Lines& lines) {
    for (const std::string& line : lines) {
      if (line.size() > ipp::kMaxLineLength) return false;
    }
    return true;
  };
  // An unknown command with a name of 65,000 characters: its error's particulars name it.
  const Lines unknown = client.transact("00002", std::string(65000, 'A') + "()");
  ASSERT_EQ(unknown.size(), 3U);
  EXPECT_EQ(unknown[1], "00002 ! Error(3, 0501, \"" + std::string(65000, 'A') + "\", \"Unsupported command\")");
  ASSERT_EQ(client.transact("00003", "ClearAllErrors()"), (Lines{"00003 &", "00003 %"}));
  const Lines info = client.transact("00004", "GetErrorInfo(501)");
  ASSERT_EQ(info.size(), 3U);
  EXPECT_TRUE(within(info)) << info[1].size() << " characters";
  EXPECT_EQ(info[1].rfind("00004 # \"Unsupported command: AAA", 0), 0U) << info[1].substr(0, 80);
  EXPECT_NO_THROW(ipp::parseReply(info[1]));

  // A data response that would be longer than the limit is an error instead.
  const Lines too_long = client.transact("00005", repeatedToolNames(4000));
  EXPECT_TRUE(within(too_long));
  EXPECT_EQ(too_long, (Lines{"00005 &", "00005 ! Error(3, 0511, \"CommandLine\", \"Error processing method\")", "00005 %"}));
}

TEST(VirtualCmmHardening, AcceptLoopBacksOffWhenOutOfDescriptors) {
  VirtualCmm server(test::quickCmmConfig());
  server.start();
  // The client's socket is made first: once descriptors run out, only connect() is left to do.
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  test::DescriptorExhaustion exhaustion;
  ASSERT_GT(exhaustion.held(), 0U);
  const sockaddr_in address = test::loopbackAddress(server.port());
  ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)), 0);  // queued

  const auto cpu_before = test::processCpuTime();
  std::this_thread::sleep_for(1s);
  EXPECT_LT(test::processCpuTime() - cpu_before, 300ms) << "the accept loop spins while out of descriptors";

  exhaustion.release();
  const std::string line = "00001 StartSession()\r\n";
  ASSERT_EQ(::send(fd, line.data(), line.size(), MSG_NOSIGNAL), static_cast<ssize_t>(line.size()));
  std::string received;
  const Clock::time_point deadline = Clock::now() + 3s;
  while (received.find("00001 %\r\n") == std::string::npos && Clock::now() < deadline) {
    std::array<char, 256> chunk{};
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    const ssize_t n = ::recv(fd, chunk.data(), chunk.size(), 0);
    if (n <= 0) break;
    received.append(chunk.data(), static_cast<std::size_t>(n));
  }
  ::close(fd);
  EXPECT_EQ(received, "00001 &\r\n00001 %\r\n") << "the queued client was not served once descriptors were free";
}

// --- The driver's deadlines --------------------------------------------------------------------

// A fake I++ DME server that answers every line correctly, one byte every `gap`.
class DribblingIppServer {
 public:
  explicit DribblingIppServer(std::chrono::milliseconds gap) : listen_fd_(test::listenOnLoopback(4, port_)) {
    thread_ = std::thread([this, gap] {
      const int fd = ::accept(listen_fd_, nullptr, nullptr);
      if (fd < 0) return;
      std::array<char, 5> tag{};
      if (::recv(fd, tag.data(), tag.size(), MSG_WAITALL) == 5) {
        const std::string reply = std::string(tag.data(), 5) + " &\r\n" + std::string(tag.data(), 5) + " %\r\n";
        for (std::size_t i = 0; i < reply.size() && !stop_; ++i) {
          if (::send(fd, &reply[i], 1, MSG_NOSIGNAL) != 1) break;
          std::this_thread::sleep_for(gap);
        }
      }
      ::close(fd);
    });
  }
  ~DribblingIppServer() {
    stop_ = true;
    ::shutdown(listen_fd_, SHUT_RDWR);
    thread_.join();
    ::close(listen_fd_);
  }
  std::uint16_t port() const { return static_cast<std::uint16_t>(port_); }

 private:
  int port_ = 0;
  int listen_fd_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST(CmmDriverDeadline, ADribbledAnswerEndsAtTheReplyDeadline) {
  DribblingIppServer server(100ms);  // 18 bytes: 1.8 s
  drivers::cmm::IppCmmOptions options;
  options.port = server.port();
  options.reply_timeout = 300ms;
  drivers::cmm::IppCmm cmm(options);
  const Clock::time_point start = Clock::now();
  try {
    cmm.connect();
    FAIL() << "an answer dribbled over seconds was accepted";
  } catch (const drivers::DeviceError& error) {
    const std::string what = error.what();
    EXPECT_EQ(error.code(), "timeout") << what;
    EXPECT_NE(what.find("CMM at 127.0.0.1:" + std::to_string(server.port())), std::string::npos) << what;
    EXPECT_NE(what.find("StartSession()\" within 300 ms"), std::string::npos) << what;
  }
  EXPECT_LT(Clock::now() - start, 3 * options.reply_timeout);
}

TEST(CmmDriverDeadline, ACmmThatNeverAcceptsIsAClearError) {
  const test::UnansweredPort unanswered;
  drivers::cmm::IppCmmOptions options;
  options.port = static_cast<std::uint16_t>(unanswered.port());
  options.connect_timeout = 300ms;
  drivers::cmm::IppCmm cmm(options);
  const Clock::time_point start = Clock::now();
  try {
    cmm.connect();
    FAIL() << "connected to a queue that is never served";
  } catch (const drivers::DeviceError& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find("CMM at 127.0.0.1:" + std::to_string(unanswered.port())), std::string::npos) << what;
    EXPECT_NE(what.find("does not answer (no connection within 300 ms)"), std::string::npos) << what;
  }
  EXPECT_LT(Clock::now() - start, 3 * options.connect_timeout);
}

}  // namespace
}  // namespace stampscan::sim
