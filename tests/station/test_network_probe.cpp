// The served virtual cell probed as an attacker and a flaky network would: a datagram that once
// crashed the fake cameras, thousands of random GVCP, Modbus TCP and I++ DME inputs, hundreds of idle
// connections, a client that never reads, and a server short of file descriptors. After each probe
// the whole cell must answer `station devices` at once (under a second).
//
// Each test runs in a private network namespace when it can make one (root, unshare(CLONE_NEWNET);
// ctest runs every test case in a process of its own), so that no other test's cameras share UDP
// 3956 with it; otherwise on the machine's loopback, under the cameras' lock.
#include "served_cell_support.hpp"

#include <sched.h>
#include <sys/resource.h>

#include <fstream>
#include <random>
#include <regex>
#include <sstream>
#include <vector>

namespace stampscan::station::test {
namespace {

// Moves this process (and what it starts) into a network namespace of its own with lo up.
bool enterPrivateNetwork() {
  if (::geteuid() != 0 || ::unshare(CLONE_NEWNET) != 0) return false;
  return std::system("ip link set lo up >/dev/null 2>&1") == 0;
}

class NetworkProbe : public StationTest {
 protected:
  void SetUp() override {
    StationTest::SetUp();
    private_network_ = enterPrivateNetwork();
    std::printf("[ probe    ] %s\n", private_network_ ? "in a private network namespace"
                                                      : "on this machine's loopback (no private network namespace)");
    port_ = basePort();
    cell_ = cellFile(work(), port_, port_ + 1, kVirtualDigitizer);
  }

  // `station devices` on the served cell: the fastest of three tries that succeed, in seconds; a
  // large number when none does. Three tries so that a busy CI machine does not decide the figure.
  double devicesAnswer(std::string* report = nullptr) {
    double best = 1e9;
    for (int attempt = 0; attempt < 3; ++attempt) {
      const auto start = std::chrono::steady_clock::now();
      const RunResult r = run("devices --cell " + quote(cell_), 20);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (report) *report = r.out + r.err;
      if (r.exit_code == 0) best = std::min(best, seconds);
    }
    return best;
  }

  void expectCellAnswers(const std::string& after) {
    std::string report;
    const double seconds = devicesAnswer(&report);
    std::printf("[ probe    ] after %s: station devices answered in %.2f s\n", after.c_str(), seconds);
    EXPECT_LT(seconds, 1.0) << "after " << after << ":\n" << report;
  }

  std::vector<pid_t> devicePids(const ServedCell& served) {
    std::vector<pid_t> pids;
    std::istringstream list(runTool("pgrep -P " + std::to_string(served.pid())).output);
    for (long pid = 0; list >> pid;) pids.push_back(static_cast<pid_t>(pid));
    return pids;
  }

  bool private_network_ = false;
  int port_ = 0;
  fs::path cell_;
};

// A blocking TCP connection to 127.0.0.1:port (with a receive buffer of `receive_buffer` bytes when
// not 0, set before connecting so that the window is small from the start); -1 when refused.
int connectTcp(int port, int receive_buffer = 0) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd >= 0 && receive_buffer > 0) ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (fd >= 0 && ::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0) return fd;
  if (fd >= 0) ::close(fd);
  return -1;
}

// Up to `count` connections to 127.0.0.1:port, all started at once and given `limit` to complete
// (a server that no longer accepts fills its listen queue, and a blocking connect would then wait
// for SYN retries); returns those that connected.
std::vector<int> connectMany(int port, int count, std::chrono::milliseconds limit) {
  std::vector<int> pending;
  for (int k = 0; k < count; ++k) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (fd < 0) break;
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0 || errno == EINPROGRESS)
      pending.push_back(fd);
    else
      ::close(fd);
  }
  std::this_thread::sleep_for(limit);
  std::vector<int> connected;
  for (const int fd : pending) {
    int error = 0;
    socklen_t length = sizeof error;
    pollfd p{fd, POLLOUT, 0};
    if (::poll(&p, 1, 0) == 1 && ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &length) == 0 && error == 0)
      connected.push_back(fd);
    else
      ::close(fd);
  }
  return connected;
}

// Reads what is there without waiting; false when the peer has closed.
bool drain(int fd, std::string* into = nullptr) {
  char buffer[4096];
  for (;;) {
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, MSG_DONTWAIT);
    if (n == 0) return false;
    if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK;
    if (into) into->append(buffer, static_cast<std::size_t>(n));
  }
}

void sendUdp(int fd, const std::string& address, const std::vector<std::uint8_t>& bytes) {
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(3956);
  ::inet_pton(AF_INET, address.c_str(), &to.sin_addr);
  ::sendto(fd, bytes.data(), bytes.size(), MSG_DONTWAIT, reinterpret_cast<const sockaddr*>(&to), sizeof to);
}

// GigE Vision GVCP: the command header (0x42, flags, command, length, request id) and a payload.
std::vector<std::uint8_t> gvcpCommand(std::uint16_t command, std::uint16_t id, const std::vector<std::uint8_t>& payload) {
  std::vector<std::uint8_t> b(8 + payload.size());
  b[0] = 0x42;
  b[1] = 0x01;  // acknowledge required
  b[2] = static_cast<std::uint8_t>(command >> 8);
  b[3] = static_cast<std::uint8_t>(command);
  b[4] = static_cast<std::uint8_t>(payload.size() >> 8);
  b[5] = static_cast<std::uint8_t>(payload.size());
  b[6] = static_cast<std::uint8_t>(id >> 8);
  b[7] = static_cast<std::uint8_t>(id);
  for (std::size_t i = 0; i < payload.size(); ++i) b[8 + i] = payload[i];
  return b;
}

// The datagram that segfaulted Aravis 0.8.26's fake camera: READMEM of 0x200 bytes at 0xfffffff0.
const std::vector<std::uint8_t> kHostileReadmem = {0x42, 0x01, 0x00, 0x84, 0x00, 0x08, 0x00, 0x07,
                                                   0xff, 0xff, 0xff, 0xf0, 0x00, 0x00, 0x02, 0x00};

TEST_F(NetworkProbe, HostileAndRandomGvcpDatagramsLeaveTheCellAnswering) {
  ServedCell served(cell_, work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  const int udp = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(udp, 0);
  for (const char* camera : {"127.0.0.1", "127.0.0.2"}) sendUdp(udp, camera, kHostileReadmem);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  expectCellAnswers("the hostile READMEM datagram");

  // 10,000 datagrams: half random bytes, half well-framed commands (discovery, register and memory
  // reads and writes, packet resend, unknown ones) with random fields, addresses and lengths.
  std::mt19937 rng(20261124);
  std::uniform_int_distribution<int> byte(0, 255), size(0, 600);
  const std::uint16_t commands[] = {0x0002, 0x0080, 0x0082, 0x0084, 0x0086, 0x0040, 0x0100, 0x1234};
  for (int k = 0; k < 10000; ++k) {
    std::vector<std::uint8_t> datagram;
    if (k % 2 == 0) {
      datagram.resize(static_cast<std::size_t>(size(rng)));
      for (auto& b : datagram) b = static_cast<std::uint8_t>(byte(rng));
    } else {
      std::vector<std::uint8_t> payload(static_cast<std::size_t>(size(rng) % 64));
      for (auto& b : payload) b = static_cast<std::uint8_t>(byte(rng));
      datagram = gvcpCommand(commands[k % 8], static_cast<std::uint16_t>(k), payload);
      if (k % 7 == 0) datagram[4] = static_cast<std::uint8_t>(byte(rng));  // a length that lies
    }
    sendUdp(udp, k % 3 == 0 ? "127.0.0.2" : "127.0.0.1", datagram);
    if (k % 64 == 0) {
      char sink[1024];
      while (::recv(udp, sink, sizeof sink, MSG_DONTWAIT) > 0) {
      }
    }
  }
  // Random writes may have taken control of a camera (CCP at 0x0a00): release it, as any controller
  // that is done does, so that the station may take it.
  for (const char* camera : {"127.0.0.1", "127.0.0.2"})
    sendUdp(udp, camera, gvcpCommand(0x0082, 0xfffe, {0x00, 0x00, 0x0a, 0x00, 0x00, 0x00, 0x00, 0x00}));
  ::close(udp);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(devicePids(served).size(), 3u) << readFile(served.log());
  EXPECT_EQ(readFile(served.log()).find("stopped unexpectedly"), std::string::npos) << readFile(served.log());
  expectCellAnswers("10,000 random GVCP datagrams");
}

TEST_F(NetworkProbe, RandomModbusFramesAndIppLinesLeaveTheCellAnswering) {
  ServedCell served(cell_, work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  std::mt19937 rng(1124);
  std::uniform_int_distribution<int> byte(0, 255);

  // Modbus TCP: MBAP header (transaction, protocol, length, unit) and a PDU; mostly well framed
  // with random function codes, addresses and counts, some with lying lengths or garbage.
  int plc = connectTcp(port_ + 1);
  ASSERT_GE(plc, 0);
  int reconnects = 0;
  for (int k = 0; k < 10000; ++k) {
    std::vector<std::uint8_t> pdu(static_cast<std::size_t>(1 + byte(rng) % 12));
    for (auto& b : pdu) b = static_cast<std::uint8_t>(byte(rng));
    if (k % 2 == 0) pdu[0] = static_cast<std::uint8_t>(1 + byte(rng) % 16);  // a real function code
    const std::size_t length = pdu.size() + 1;
    std::vector<std::uint8_t> frame = {static_cast<std::uint8_t>(k >> 8), static_cast<std::uint8_t>(k), 0, 0,
                                       static_cast<std::uint8_t>(length >> 8), static_cast<std::uint8_t>(length),
                                       static_cast<std::uint8_t>(k % 5 == 0 ? byte(rng) : 1)};
    if (k % 11 == 0) frame[2] = static_cast<std::uint8_t>(byte(rng));  // another protocol id
    if (k % 13 == 0) frame[5] = static_cast<std::uint8_t>(byte(rng));  // a length that lies
    frame.insert(frame.end(), pdu.begin(), pdu.end());
    if (::send(plc, frame.data(), frame.size(), MSG_NOSIGNAL) < 0 || !drain(plc)) {
      ::close(plc);  // the server hung up on a frame it refused: go on with a new connection
      plc = connectTcp(port_ + 1);
      ASSERT_GE(plc, 0) << "the PLC stopped accepting after " << k << " frames";
      ++reconnects;
    }
  }
  ::close(plc);
  std::printf("[ probe    ] modbus: 10,000 frames, the server closed the connection %d times\n", reconnects);
  expectCellAnswers("10,000 random Modbus TCP frames");

  // I++ DME: tagged lines of real and invented commands with random arguments, and raw garbage.
  const char* words[] = {"StartSession()", "EndSession()", "Get(X(),Y(),Z())", "GoTo(X(", "Home()", "GetErrorInfo(",
                         "ClearAllErrors()", "EnumTools()", "GetProp(Tool.A())", "OnMoveReportE(", "AbortE()",
                         "SetProp(Tool.GoToPar.Speed(", "IsHomed()", "ChangeTool(\"", "Frobnicate("};
  int cmm = connectTcp(port_);
  ASSERT_GE(cmm, 0);
  for (int k = 0; k < 10000; ++k) {
    std::string line;
    if (k % 4 == 3) {
      for (int n = byte(rng) % 80; n > 0; --n) line.push_back(static_cast<char>(byte(rng)));
    } else {
      char tag[8];
      std::snprintf(tag, sizeof tag, "%05d", k % 100000);
      line = std::string(tag) + " " + words[k % 15];
      for (int n = byte(rng) % 6; n > 0; --n) line += std::to_string(byte(rng) - 128) + (n > 1 ? "," : ")");
    }
    line += "\r\n";
    if (::send(cmm, line.data(), line.size(), MSG_NOSIGNAL) < 0 || !drain(cmm)) {
      ::close(cmm);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      cmm = connectTcp(port_);
      ASSERT_GE(cmm, 0) << "the CMM stopped accepting after " << k << " lines";
    }
  }
  ::close(cmm);
  EXPECT_EQ(readFile(served.log()).find("stopped unexpectedly"), std::string::npos) << readFile(served.log());
  expectCellAnswers("10,000 random I++ DME lines");
}

TEST_F(NetworkProbe, IdleConnectionsAndASlowReaderAreLetGo) {
  ServedCell served(cell_, work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  // 200 idle connections to each server, held for a while, then closed.
  std::vector<int> idle = connectMany(port_, 200, std::chrono::seconds(1));
  for (const int fd : connectMany(port_ + 1, 200, std::chrono::seconds(1))) idle.push_back(fd);
  std::printf("[ probe    ] %zu idle connections open\n", idle.size());
  std::this_thread::sleep_for(std::chrono::seconds(3));
  for (const int fd : idle) ::close(fd);
  expectCellAnswers("200 idle connections to the CMM and to the PLC");

  // A client that keeps sending commands and never reads: the CMM must close the connection
  // rather than block on it (its send deadline is seconds), and every line that went out is whole.
  const int slow = connectTcp(port_, 4096);
  ASSERT_GE(slow, 0);
  std::string commands = "00001 StartSession()\r\n";
  for (int k = 2; k < 2000; ++k) {
    char line[48];
    std::snprintf(line, sizeof line, "%05d Get(X(),Y(),Z())\r\n", k);
    commands += line;
  }
  bool closed = false;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!closed && std::chrono::steady_clock::now() < give_up) {
    const ssize_t n = ::send(slow, commands.data(), commands.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) closed = true;  // reset by the server
    else std::this_thread::sleep_for(std::chrono::milliseconds(n < 0 ? 50 : 1));
  }
  std::string received;
  while (drain(slow, &received) && !received.empty() && received.size() < (1u << 26)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    const std::size_t before = received.size();
    drain(slow, &received);
    if (received.size() == before) break;
  }
  ::close(slow);
  EXPECT_TRUE(closed) << "the CMM kept a connection whose client does not read for 30 s";
  // Every complete line is one whole response ("tag kind ..."): a line cut short and run into the
  // next one would show as a malformed line. The closing reset may drop the tail of what was in
  // flight, so the last fragment, without its line end, is not judged.
  const std::regex response(R"(^(\d{5}|E\d{4}) [&%#!]( .*)?$)");
  std::size_t lines = 0;
  for (std::size_t start = 0, end; (end = received.find("\r\n", start)) != std::string::npos; start = end + 2, ++lines) {
    const std::string line = received.substr(start, end - start);
    ASSERT_TRUE(std::regex_match(line, response)) << "line " << lines << " is not one whole response: " << line;
  }
  std::printf("[ probe    ] the slow reader got %zu whole lines before the CMM closed its connection\n", lines);
  expectCellAnswers("a client that never reads");
}

TEST_F(NetworkProbe, ServersShortOfFileDescriptorsBackOffAndRecover) {
  // The served cell with few descriptors, then more connections than it has: its accept loops must
  // not spin, and it must serve again once the connections are gone.
  ServedCell served(cell_, work(), "ulimit -n 128; ");
  ASSERT_NO_FATAL_FAILURE(served.start());
  const std::vector<pid_t> devices = devicePids(served);
  ASSERT_EQ(devices.size(), 3u);
  const auto cpuTicks = [&] {
    long total = 0;
    for (const pid_t pid : devices) {
      std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
      std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
      std::istringstream fields(text.substr(text.rfind(')') + 2));
      std::string field;
      for (int k = 3; k <= 15 && fields >> field; ++k) {
        if (k == 14 || k == 15) total += std::stol(field);  // utime, stime
      }
    }
    return total;
  };
  std::vector<int> flood = connectMany(port_, 300, std::chrono::seconds(1));
  for (const int fd : connectMany(port_ + 1, 300, std::chrono::seconds(1))) flood.push_back(fd);
  const long before = cpuTicks();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  const double cpu_seconds = static_cast<double>(cpuTicks() - before) / static_cast<double>(::sysconf(_SC_CLK_TCK));
  std::printf("[ probe    ] %zu connections; the cell's processes used %.2f s of CPU in 2 s\n", flood.size(), cpu_seconds);
  EXPECT_LT(cpu_seconds, 0.5) << "an accept loop spins when descriptors run out";
  for (const int fd : flood) ::close(fd);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  expectCellAnswers("descriptor exhaustion");
}

}  // namespace
}  // namespace stampscan::station::test
