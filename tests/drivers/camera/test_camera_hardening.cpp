// Hostile and foreign GVCP traffic against the virtual cameras, and a second controller seen by the
// driver: the cameras answer malformed requests with the GigE Vision error status and keep
// streaming, listen on loopback only, and the driver names a camera that another application holds.
#include <arpa/inet.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <fstream>
#include <optional>
#include <random>
#include <sstream>

#include "camera_test_support.hpp"

namespace stampscan::test {
namespace {

using drivers::camera::CameraConfig;
using drivers::camera::GigECamera;
using Bytes = std::vector<std::uint8_t>;

constexpr std::uint16_t kGvcpPort = 3956;
// GVCP status codes (GigE Vision 2.0).
constexpr std::uint16_t GEV_STATUS_SUCCESS = 0x0000, GEV_STATUS_NOT_IMPLEMENTED = 0x8001,
                        GEV_STATUS_INVALID_PARAMETER = 0x8002, GEV_STATUS_INVALID_ADDRESS = 0x8003,
                        GEV_STATUS_WRITE_PROTECT = 0x8004, GEV_STATUS_BAD_ALIGNMENT = 0x8005,
                        GEV_STATUS_ACCESS_DENIED = 0x8006, GEV_STATUS_INVALID_HEADER = 0x800E;
constexpr std::uint32_t kCcp = 0x0A00, kHeartbeatTimeout = 0x0938;

// The tester's datagram: READMEM of 0x200 bytes at 0xfffffff0. It crashed Aravis 0.8.26's own fake
// GigE Vision camera, and the whole process with it.
const Bytes kHostileReadMem{0x42, 0x01, 0x00, 0x84, 0x00, 0x08, 0x00, 0x07,
                            0xff, 0xff, 0xff, 0xf0, 0x00, 0x00, 0x02, 0x00};

void put16(Bytes& b, std::uint16_t v) {
  b.push_back(static_cast<std::uint8_t>(v >> 8));
  b.push_back(static_cast<std::uint8_t>(v));
}
void put32(Bytes& b, std::uint32_t v) {
  put16(b, static_cast<std::uint16_t>(v >> 16));
  put16(b, static_cast<std::uint16_t>(v));
}

Bytes command(std::uint16_t code, const Bytes& payload, std::uint16_t id) {
  Bytes b{0x42, 0x01};
  put16(b, code);
  put16(b, static_cast<std::uint16_t>(payload.size()));
  put16(b, id);
  b.insert(b.end(), payload.begin(), payload.end());
  return b;
}
Bytes readReg(std::uint32_t address, std::uint16_t id = 1) {
  Bytes p;
  put32(p, address);
  return command(0x0080, p, id);
}
Bytes writeReg(std::uint32_t address, std::uint32_t value, std::uint16_t id = 1) {
  Bytes p;
  put32(p, address);
  put32(p, value);
  return command(0x0082, p, id);
}
Bytes readMem(std::uint32_t address, std::uint16_t count, std::uint16_t id = 1) {
  Bytes p;
  put32(p, address);
  put16(p, 0);
  put16(p, count);
  return command(0x0084, p, id);
}

// The acknowledge's status; 0xFFFF when there was no (complete) acknowledge.
std::uint16_t status(const std::optional<Bytes>& reply) {
  if (!reply || reply->size() < 8) return 0xFFFF;
  return static_cast<std::uint16_t>((*reply)[0] << 8 | (*reply)[1]);
}

// A GVCP client on its own UDP socket (so a controller distinct from the driver under test).
class GvcpClient {
 public:
  explicit GvcpClient(const char* bind_address = "127.0.0.1") {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    inet_pton(AF_INET, bind_address, &a.sin_addr);
    bound_ = fd_ >= 0 && ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~GvcpClient() {
    if (fd_ >= 0) ::close(fd_);
  }
  GvcpClient(const GvcpClient&) = delete;
  GvcpClient& operator=(const GvcpClient&) = delete;
  bool ok() const { return bound_; }
  int fd() const { return fd_; }

  bool send(const std::string& address, const Bytes& datagram, std::uint16_t port = kGvcpPort) {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    inet_pton(AF_INET, address.c_str(), &to.sin_addr);
    return ::sendto(fd_, datagram.data(), datagram.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to) ==
           static_cast<ssize_t>(datagram.size());
  }
  std::optional<Bytes> receive(std::chrono::milliseconds timeout) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout.count())) <= 0) return std::nullopt;
    Bytes buffer(2048);
    const ssize_t n = ::recv(fd_, buffer.data(), buffer.size(), 0);
    if (n < 0) return std::nullopt;
    buffer.resize(static_cast<std::size_t>(n));
    return buffer;
  }
  void drain() {
    while (receive(std::chrono::milliseconds(0))) {
    }
  }
  // One request and its acknowledge: the first reply carrying the request's id (late replies to
  // earlier requests are skipped). A generous timeout: the machine may be loaded.
  std::optional<Bytes> exchange(const std::string& address, const Bytes& request,
                                std::chrono::milliseconds timeout = std::chrono::milliseconds(2000)) {
    drain();
    if (request.size() < 8 || !send(address, request)) return std::nullopt;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() < 0) return std::nullopt;
      auto reply = receive(left);
      if (!reply) return std::nullopt;
      if (reply->size() >= 8 && (*reply)[6] == request[6] && (*reply)[7] == request[7]) return reply;
    }
  }

 private:
  int fd_ = -1;
  bool bound_ = false;
};

class CameraHardening : public VirtualCamerasTest {
 protected:
  static CameraConfig smallFreeRun() {
    CameraConfig c;
    c.roi = {0, 0, 320, 240};
    c.frame_rate_hz = 50.0;
    c.packet_size = 8192;
    return c;
  }
};

TEST_F(CameraHardening, HostileRequestsGetTheirErrorStatusAndTheCameraStreamsOn) {
  GvcpClient rogue;
  ASSERT_TRUE(rogue.ok());
  for (const char* address : {kLeftAddress, kRightAddress}) {
    const auto reply = rogue.exchange(address, kHostileReadMem);
    ASSERT_TRUE(reply) << "no answer from " << address << " to the hostile READMEM";
    ASSERT_EQ(reply->size(), 12u);  // header + the echoed address
    EXPECT_EQ(status(reply), GEV_STATUS_INVALID_ADDRESS);
    EXPECT_EQ((Bytes{(*reply)[2], (*reply)[3], (*reply)[6], (*reply)[7]}), (Bytes{0x00, 0x85, 0x00, 0x07}));
    EXPECT_EQ((Bytes(reply->begin() + 8, reply->end())), (Bytes{0xff, 0xff, 0xff, 0xf0}));
  }
  struct Case {
    const char* what;
    Bytes request;
    std::uint16_t expected;
  };
  Bytes too_long = readReg(0);
  too_long[5] = 0x40;  // declares 64 bytes of payload, carries 4
  const std::vector<Case> cases{
      {"READMEM of 0 bytes", readMem(0x0000, 0), GEV_STATUS_INVALID_PARAMETER},
      {"READMEM of 1000 bytes", readMem(0x0000, 1000), GEV_STATUS_INVALID_PARAMETER},
      {"READMEM at an odd address", readMem(0x0001, 4), GEV_STATUS_BAD_ALIGNMENT},
      {"READMEM past the XML", readMem(0x20000, 512), GEV_STATUS_INVALID_ADDRESS},
      {"READREG of 3 bytes", command(0x0080, Bytes{0, 0, 0}, 1), GEV_STATUS_INVALID_PARAMETER},
      {"READREG at 0xfffffffc", readReg(0xfffffffc), GEV_STATUS_INVALID_ADDRESS},
      {"length beyond the datagram", too_long, GEV_STATUS_INVALID_HEADER},
      {"unknown command", command(0x1234, {}, 1), GEV_STATUS_NOT_IMPLEMENTED},
      {"write without control", writeReg(0x0100, 64), GEV_STATUS_ACCESS_DENIED},
      {"READMEM of the bootstrap", readMem(0x0000, 0x48), GEV_STATUS_SUCCESS},
  };
  for (const Case& c : cases) {
    const auto reply = rogue.exchange(kLeftAddress, c.request);
    ASSERT_TRUE(reply) << c.what << ": no answer";
    EXPECT_EQ(status(reply), c.expected) << c.what;
  }
  // As controller: a read-only bootstrap register (the serial number) is write-protected.
  ASSERT_EQ(status(rogue.exchange(kRightAddress, writeReg(kCcp, 2))), GEV_STATUS_SUCCESS);
  EXPECT_EQ(status(rogue.exchange(kRightAddress, writeReg(0x00D8, 0x41414141))), GEV_STATUS_WRITE_PROTECT);
  EXPECT_EQ(status(rogue.exchange(kRightAddress, writeReg(kCcp, 0))), GEV_STATUS_SUCCESS);

  GigECamera cam("left", options(kLeftSerial, kLeftAddress));
  cam.connect();
  cam.configure(smallFreeRun());
  FrameSink frames;
  cam.startStreaming(std::ref(frames));
  EXPECT_TRUE(frames.waitFor(5, std::chrono::seconds(5)));
  cam.stopStreaming();
  for (const auto& f : frames.frames()) EXPECT_TRUE(imageIsIntact(1, f.info.bytes)) << "frame " << f.info.frame_id;
}

// Mutations of valid requests, plain random bytes and the hostile datagram, from another
// application while the driver streams from both cameras.
TEST_F(CameraHardening, RandomAndMutatedDatagramsLeaveBothCamerasAnsweringAndStreaming) {
  GigECamera left("left", options(kLeftSerial, kLeftAddress));
  GigECamera right("right", options(kRightSerial, kRightAddress));
  left.connect();
  right.connect();
  left.configure(smallFreeRun());
  right.configure(smallFreeRun());
  FrameSink left_frames, right_frames;
  left.startStreaming(std::ref(left_frames));
  right.startStreaming(std::ref(right_frames));
  ASSERT_TRUE(left_frames.waitFor(3, std::chrono::seconds(5)));
  ASSERT_TRUE(right_frames.waitFor(3, std::chrono::seconds(5)));

  const std::vector<Bytes> seeds{command(0x0002, {}, 0xffff), readReg(0x0000), readReg(kCcp), writeReg(kCcp, 2),
                                 writeReg(0x0124, 1), writeReg(0x0D00, 40000), readMem(0x0200, 64),
                                 readMem(0x10000, 512), command(0x0086, Bytes(12, 0x11), 3), kHostileReadMem};
  std::mt19937_64 random(20240611);  // fixed: a failure replays
  const auto below = [&random](std::size_t n) { return n == 0 ? std::size_t{0} : std::size_t(random() % n); };
  GvcpClient rogue;
  ASSERT_TRUE(rogue.ok());
  constexpr int kDatagrams = 3000;
  for (int i = 0; i < kDatagrams; ++i) {
    Bytes d;
    if (i % 10 == 0) {
      d.resize(below(600));
      for (auto& byte : d) byte = static_cast<std::uint8_t>(random());
    } else {
      d = seeds[below(seeds.size())];
      for (std::size_t k = 1 + below(4); k > 0; --k) {
        switch (below(5)) {
          case 0: if (!d.empty()) d[below(d.size())] ^= static_cast<std::uint8_t>(1u << below(8)); break;
          case 1: if (!d.empty()) d[below(d.size())] = std::array<std::uint8_t, 4>{0x00, 0xff, 0x80, 0x7f}[below(4)]; break;
          case 2: d.resize(below(d.size() + 1)); break;
          case 3: d.resize(d.size() + below(32), static_cast<std::uint8_t>(random())); break;
          default: if (d.size() >= 8) d[4 + below(2)] = static_cast<std::uint8_t>(random()); break;  // the length
        }
      }
    }
    rogue.send(i % 2 == 0 ? kLeftAddress : kRightAddress, d);
    if (i % 100 == 99) rogue.drain();
  }
  rogue.drain();
  for (const char* address : {kLeftAddress, kRightAddress}) {
    // The flood may still fill the camera's socket queue, and UDP drops what does not fit (that is
    // why GVCP clients retry): up to three tries.
    std::optional<Bytes> reply;
    for (int attempt = 0; attempt < 3 && !reply; ++attempt) {
      reply = rogue.exchange(address, readReg(0x0000, static_cast<std::uint16_t>(0x4240 + attempt)),
                             std::chrono::milliseconds(1000));
    }
    ASSERT_TRUE(reply) << address << " no longer answers GVCP";
    EXPECT_EQ(status(reply), GEV_STATUS_SUCCESS);
  }
  const std::size_t left_before = left_frames.size(), right_before = right_frames.size();
  EXPECT_TRUE(left_frames.waitFor(left_before + 5, std::chrono::seconds(5))) << "left stopped streaming";
  EXPECT_TRUE(right_frames.waitFor(right_before + 5, std::chrono::seconds(5))) << "right stopped streaming";
  EXPECT_FALSE(hasFault(left, "disconnected"));
  EXPECT_FALSE(hasFault(right, "disconnected"));
  left.stopStreaming();
  right.stopStreaming();
  // Every frame that came during and after the flood is whole. (The right camera's first frames
  // are left out: Aravis' packet-socket receiver can take in a few packets of the left camera's
  // stream while its filter is not yet attached, a known issue of the driver, not of the cameras.)
  for (const auto& f : left_frames.frames()) EXPECT_TRUE(imageIsIntact(1, f.info.bytes));
  const auto right_got = right_frames.frames();
  for (std::size_t i = right_before; i < right_got.size(); ++i) EXPECT_TRUE(imageIsIntact(2, right_got[i].info.bytes));
}

// The first IPv4 address of this host that is not on lo, if any.
std::optional<std::string> nonLoopbackAddress() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return std::nullopt;
  std::optional<std::string> found;
  for (ifaddrs* i = list; i != nullptr && !found; i = i->ifa_next) {
    if (i->ifa_addr == nullptr || i->ifa_addr->sa_family != AF_INET || (i->ifa_flags & IFF_LOOPBACK) != 0 ||
        (i->ifa_flags & IFF_UP) == 0) {
      continue;
    }
    char text[INET_ADDRSTRLEN] = {};
    sockaddr_in in{};
    std::memcpy(&in, i->ifa_addr, sizeof in);
    inet_ntop(AF_INET, &in.sin_addr, text, sizeof text);
    found = text;
  }
  freeifaddrs(list);
  return found;
}

TEST_F(CameraHardening, ListensOnLoopbackOnly) {
  // No GVCP socket bound to the wildcard address (it would take requests from every interface).
  std::ifstream udp("/proc/net/udp");
  ASSERT_TRUE(udp) << "cannot read /proc/net/udp";
  std::string line;
  std::getline(udp, line);  // the column titles
  int gvcp_sockets = 0;
  while (std::getline(udp, line)) {
    std::istringstream fields(line);
    std::string slot, local;
    fields >> slot >> local;  // "0100007F:0F74": address (little-endian hex) and port
    const std::size_t colon = local.find(':');
    if (colon == std::string::npos || std::stoul(local.substr(colon + 1), nullptr, 16) != kGvcpPort) continue;
    const std::uint32_t address = ntohl(static_cast<std::uint32_t>(std::stoul(local.substr(0, colon), nullptr, 16)));
    ++gvcp_sockets;
    EXPECT_TRUE((address >> 24) == 127 || address == INADDR_BROADCAST)
        << "a socket on UDP 3956 is bound to " << local.substr(0, colon) << " (not loopback)";
  }
  EXPECT_GE(gvcp_sockets, 2);

  // Loopback discovery works (arv_update_device_list, arv-tool): both cameras answer a broadcast
  // sent on lo ...
  GvcpClient local;
  ASSERT_TRUE(local.ok());
  const int on = 1;
  setsockopt(local.fd(), SOL_SOCKET, SO_BROADCAST, &on, sizeof on);
  ASSERT_TRUE(local.send("255.255.255.255", command(0x0002, {}, 0xffff)));
  int answers = 0;
  while (local.receive(std::chrono::milliseconds(500))) ++answers;
  EXPECT_GE(answers, 2) << "the cameras do not answer a discovery broadcast on lo";

  // ... but nothing from another interface reaches them, broadcast or unicast.
  const std::optional<std::string> outside = nonLoopbackAddress();
  if (!outside) GTEST_SKIP() << "this host has no non-loopback IPv4 address to test from";
  GvcpClient foreign(outside->c_str());
  ASSERT_TRUE(foreign.ok()) << "cannot bind to " << *outside;
  setsockopt(foreign.fd(), SOL_SOCKET, SO_BROADCAST, &on, sizeof on);
  foreign.send("255.255.255.255", command(0x0002, {}, 0xffff));
  foreign.send(*outside, command(0x0002, {}, 0xfffe));
  foreign.send(*outside, kHostileReadMem);
  EXPECT_FALSE(foreign.receive(std::chrono::milliseconds(500)))
      << "a virtual camera answered a request from " << *outside;
}

TEST_F(CameraHardening, SecondControllerIsReportedQuickly) {
  GvcpClient other;  // another application, holding the left camera
  ASSERT_TRUE(other.ok());
  ASSERT_EQ(status(other.exchange(kLeftAddress, writeReg(kCcp, 2))), GEV_STATUS_SUCCESS);

  GigECamera cam("camera_l", options(kLeftSerial, kLeftAddress));
  const auto t0 = std::chrono::steady_clock::now();
  try {
    cam.connect();
    FAIL() << "connected to a camera another application controls";
  } catch (const drivers::DeviceError& e) {
    const std::string text = e.what();
    EXPECT_EQ(e.code(), "controlled") << text;
    EXPECT_NE(text.find(std::string("camera ") + kLeftSerial + " at 127.0.0.1 is controlled by another application "
                                                               "(CCP held)"),
              std::string::npos)
        << text;
  }
  const auto elapsed = std::chrono::steady_clock::now() - t0;
  // About 40 GVCP round trips on loopback; the bound leaves room for a loaded machine.
  EXPECT_LT(elapsed, std::chrono::milliseconds(1500))
      << std::chrono::duration_cast<std::chrono::milliseconds>(elapsed).count() << " ms";
  EXPECT_EQ(cam.state(), drivers::DeviceState::Faulted);
  EXPECT_FALSE(cam.check());
  EXPECT_TRUE(hasFault(cam, "controlled"));

  // The other application lets go: the camera is ours.
  ASSERT_EQ(status(other.exchange(kLeftAddress, writeReg(kCcp, 0))), GEV_STATUS_SUCCESS);
  cam.connect();
  EXPECT_TRUE(cam.check());
  // And now the other one is refused, as we were.
  EXPECT_EQ(status(other.exchange(kLeftAddress, writeReg(kCcp, 2))), GEV_STATUS_ACCESS_DENIED);
  EXPECT_TRUE(cam.check());
}

TEST_F(CameraHardening, AnAbandonedControllerLosesTheCameraAfterItsHeartbeatTimeout) {
  GvcpClient other;
  ASSERT_TRUE(other.ok());
  ASSERT_EQ(status(other.exchange(kRightAddress, writeReg(kCcp, 2))), GEV_STATUS_SUCCESS);
  ASSERT_EQ(status(other.exchange(kRightAddress, writeReg(kHeartbeatTimeout, 500))), GEV_STATUS_SUCCESS);
  const auto held = other.exchange(kRightAddress, readReg(kCcp));
  ASSERT_TRUE(held);
  EXPECT_EQ(held->back() & 0x3, 0x2) << "CCP does not show the control bit";
  // The other application goes silent; the camera releases it after 500 ms without a heartbeat.
  GigECamera cam("right", options(kRightSerial, kRightAddress));
  EXPECT_TRUE(waitUntil(
      [&] {
        try {
          cam.connect();
          return true;
        } catch (const drivers::DeviceError&) {
          std::this_thread::sleep_for(std::chrono::milliseconds(100));
          return false;
        }
      },
      std::chrono::seconds(5)));
  EXPECT_TRUE(cam.check());
  // The heartbeat timeout went back to its default with the session that set it.
  const auto timeout = other.exchange(kRightAddress, readReg(kHeartbeatTimeout));
  ASSERT_TRUE(timeout);
  EXPECT_EQ(status(timeout), GEV_STATUS_SUCCESS);
  EXPECT_EQ((Bytes(timeout->begin() + 8, timeout->end())), (Bytes{0x00, 0x00, 0x0b, 0xb8}));  // 3000 ms
}

}  // namespace
}  // namespace stampscan::test
