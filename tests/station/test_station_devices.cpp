// `station sim serve` and `station devices`: the virtual cell on loopback, found and checked through
// the real drivers, with the virtual digitizer hosted in the devices command's own process; the
// served devices also answer independent tools (arv-tool, mbpoll, a plain TCP client speaking
// I++ DME); missing devices and bad cell files give clear reports and a non-zero exit.
#include "station_test_support.hpp"

#include "stampscan/drivers/plc/plc_register_map.hpp"
#include "stampscan/sim/virtual_cmm.hpp"
#include "stampscan/acquisition/cell_config.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>
#include <sstream>
#include <thread>

#ifndef STAMPSCAN_VIRTUAL_CELL_FILE
#error "STAMPSCAN_VIRTUAL_CELL_FILE must name station/cells/virtual.toml"
#endif

namespace stampscan::station::test {

using acquisition::CellConfig;
using acquisition::loadCellConfig;
using acquisition::virtualCell;
namespace {

// The [digitizer] section of a cell whose digitizer is the virtual one, hosted by `station devices`.
constexpr const char* kVirtualDigitizer = "virtual = true\nrequired = true\n";
// ... and of a cell that lets the digitizer be absent (no virtual key: a real USB device).
constexpr const char* kOptionalDigitizer = "required = false\n";

// A cell file on ports of its own, so that tests running in parallel do not collide; the cameras
// are the defaults (STAMPSCAN-LEFT on 127.0.0.1, STAMPSCAN-RIGHT on 127.0.0.2).
fs::path cellFile(const fs::path& dir, int cmm_port, int plc_port, const std::string& digitizer = kOptionalDigitizer,
                  const std::string& name = "cell.toml") {
  const fs::path file = dir / name;
  writeFile(file, "name = \"test cell\"\n[cmm]\nhost = \"127.0.0.1\"\nport = " + std::to_string(cmm_port) +
                      "\n[plc]\nhost = \"127.0.0.1\"\nport = " + std::to_string(plc_port) + "\n[digitizer]\n" + digitizer);
  return file;
}

int basePort() { return 20000 + static_cast<int>(getpid() % 20000); }

// The Aravis device ids of the served fake cameras: "Aravis-Fake-<serial>".
constexpr const char* kLeftCameraId = "Aravis-Fake-STAMPSCAN-LEFT";
constexpr const char* kRightCameraId = "Aravis-Fake-STAMPSCAN-RIGHT";

// `station sim serve --for 30 --cell CELL` in the background, from start() until this object goes
// away: then SIGTERM, waited for, so that the fake cameras have left UDP 3956 when the next camera
// test starts. The tests that serve take the cameras' lock (station_test_lock.cmake).
class ServedCell {
 public:
  ServedCell(fs::path cell, fs::path dir) : cell_(std::move(cell)), dir_(std::move(dir)) {}
  ServedCell(const ServedCell&) = delete;
  ServedCell& operator=(const ServedCell&) = delete;
  ~ServedCell() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    for (int i = 0; i < 100 && ::kill(pid_, 0) == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }

  // Starts serving and waits until the server says it runs; fails the test (fatally) otherwise.
  void start() {
    const fs::path pid_file = dir_ / "serve.pid";
    const std::string serve = "sh -c 'echo $$ > " + pid_file.string() + "; exec " + std::string(STATION_EXE) +
                              " sim serve --for 30 --cell " + cell_.string() + "' >" + quote(log()) + " 2>&1 &";
    ASSERT_EQ(std::system(serve.c_str()), 0);
    for (int attempt = 0; attempt < 50 && pid_ == 0; ++attempt) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      const std::string text = readFile(pid_file);
      if (!text.empty() && text.back() == '\n') pid_ = static_cast<pid_t>(std::stol(text));
    }
    ASSERT_GT(pid_, 0) << "station sim serve did not start";
    for (int attempt = 0; attempt < 200; ++attempt) {  // 10 s
      const std::string text = readFile(log());
      if (text.find("  running;") != std::string::npos) return;
      ASSERT_EQ(::kill(pid_, 0), 0) << "station sim serve stopped:\n" << text;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    FAIL() << "station sim serve did not say it runs within 10 s:\n" << readFile(log());
  }

  fs::path log() const { return dir_ / "serve.txt"; }
  pid_t pid() const { return pid_; }

 private:
  fs::path cell_, dir_;
  pid_t pid_ = 0;
};

// A program's output (stdout and stderr) and exit status, through /bin/sh; -1 when it could not run.
struct ToolRun {
  int exit_status = -1;
  std::string output;
};

ToolRun runTool(const std::string& command) {
  ToolRun r;
  std::FILE* pipe = ::popen(("timeout 20 " + command + " 2>&1 </dev/null").c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 512> buffer{};
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) r.output += buffer.data();
  const int status = ::pclose(pipe);
  r.exit_status = status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

bool installed(const std::string& program) {
  return std::system(("command -v " + program + " >/dev/null 2>&1").c_str()) == 0;
}

// A plain TCP client speaking lines, with POSIX sockets only: nothing of the project's drivers.
class LineClient {
 public:
  LineClient() = default;
  LineClient(const LineClient&) = delete;
  LineClient& operator=(const LineClient&) = delete;
  ~LineClient() {
    if (fd_ >= 0) ::close(fd_);
  }

  // Connects to 127.0.0.1:port; "" when connected, otherwise what went wrong.
  std::string connect(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd_ < 0) return std::string("socket: ") + std::strerror(errno);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0)
      return "connect to 127.0.0.1:" + std::to_string(port) + ": " + std::strerror(errno);
    return "";
  }

  bool send(const std::string& bytes) const {
    std::size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<std::size_t>(n);
    }
    return true;
  }

  // The next line, with its line end (CR LF by the protocol, checked by the caller); nothing when
  // none came within `limit` or the server hung up.
  std::optional<std::string> line(std::chrono::milliseconds limit = std::chrono::seconds(5)) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    for (;;) {
      if (const auto end = pending_.find('\n'); end != std::string::npos) {
        std::string line = pending_.substr(0, end + 1);
        pending_.erase(0, end + 1);
        return line;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      pollfd p{fd_, POLLIN, 0};
      if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) return std::nullopt;
      char buffer[512];
      const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
      if (n <= 0) return std::nullopt;
      pending_.append(buffer, static_cast<std::size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  std::string pending_;
};

// Each served device runs in a process of its own: one that crashes (here: killed by SIGSEGV, as
// the fake camera once was by a hostile datagram) leaves the others answering and is started again.
TEST_F(StationTest, AFaultInOneServedDeviceLeavesTheOthersRunning) {
  const int port = basePort();
  const fs::path cell = cellFile(work(), port, port + 1, kVirtualDigitizer);
  ServedCell served(cell, work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  const ToolRun children = runTool("pgrep -P " + std::to_string(served.pid()));
  std::vector<pid_t> pids;
  std::istringstream list(children.output);
  for (long pid = 0; list >> pid;) pids.push_back(static_cast<pid_t>(pid));
  ASSERT_EQ(pids.size(), 3u) << "one process per device (cmm, plc, cameras): " << children.output;
  for (std::size_t k = 0; k < pids.size(); ++k) {
    ASSERT_EQ(::kill(pids[k], SIGSEGV), 0);
    RunResult r;
    for (int attempt = 0; attempt < 40; ++attempt) {  // until the device is served again
      r = run("devices --cell " + quote(cell));
      if (r.exit_code == 0) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
    EXPECT_EQ(r.exit_code, 0) << "after killing device process " << k << ":\n" << r.out << r.err << readFile(served.log());
  }
  const std::string log = readFile(served.log());
  std::size_t restarts = 0;
  for (std::size_t at = 0; (at = log.find("serving again", at)) != std::string::npos; ++at) ++restarts;
  EXPECT_EQ(restarts, 3u) << log;
  EXPECT_NE(log.find("stopped unexpectedly (killed by signal 11"), std::string::npos) << log;
}

TEST_F(StationTest, DevicesFindsTheServedVirtualCell) {
  const int port = basePort();
  const fs::path cell = cellFile(work(), port, port + 1, kVirtualDigitizer);
  ServedCell served(cell, work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  EXPECT_NE(readFile(served.log()).find("hosted in-process by `station devices`"), std::string::npos)
      << readFile(served.log());

  // The virtual digitizer, hosted by `station devices` itself (under umockdev), is found and required.
  RunResult r;
  for (int attempt = 0; attempt < 50; ++attempt) {  // until the servers answer
    r = run("devices --cell " + quote(cell));
    if (r.exit_code == 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("cmm        127.0.0.1:" + std::to_string(port)), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("I++ DME"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("plc"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("camera_l   127.0.0.1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("camera_r   127.0.0.2"), std::string::npos) << r.out;
  const auto digitizer = r.out.find("digitizer  usb 1d50:61a5");
  ASSERT_NE(digitizer, std::string::npos) << r.out;
  const std::string row = r.out.substr(digitizer, r.out.find('\n', digitizer) - digitizer);
  EXPECT_NE(row.find("StampScan SSD-1024 (virtual) #VD-0001"), std::string::npos) << row;
  EXPECT_NE(row.find("1.0.0"), std::string::npos) << row;
  EXPECT_NE(row.find("ready"), std::string::npos) << row;
  EXPECT_NE(r.out.find("hosted in this process under umockdev"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("all required devices answered"), std::string::npos) << r.out;

  // A cell without the virtual digitizer that does not require one: still all right without it.
  r = run("devices --cell " + quote(cellFile(work(), port, port + 1, kOptionalDigitizer, "optional.toml")));
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("(optional in this cell)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("hosted in this process"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("all required devices answered"), std::string::npos) << r.out;
}

TEST_F(StationTest, ArvToolTalksToTheServedCameras) {
  if (!installed("arv-tool-0.8"))
    GTEST_SKIP() << "arv-tool-0.8 is not installed (apt-get install aravis-tools-cli); the check with "
                    "Aravis's own command-line tool is skipped";
  const int port = basePort();
  ServedCell served(cellFile(work(), port, port + 1), work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  const ToolRun list = runTool("arv-tool-0.8");
  EXPECT_EQ(list.exit_status, 0) << list.output;
  EXPECT_NE(list.output.find(std::string(kLeftCameraId) + " (127.0.0.1)"), std::string::npos) << list.output;
  EXPECT_NE(list.output.find(std::string(kRightCameraId) + " (127.0.0.2)"), std::string::npos) << list.output;
  for (const char* id : {kLeftCameraId, kRightCameraId}) {
    // arv-tool exits 0 even for an unknown feature, so the answer is read: "Width = 512 min:1 max:2048".
    const ToolRun width = runTool(std::string("arv-tool-0.8 -n ") + id + " control Width");
    EXPECT_EQ(width.exit_status, 0) << id << ": " << width.output;
    long value = 0;
    EXPECT_EQ(std::sscanf(width.output.c_str(), "Width = %ld", &value), 1) << id << ": " << width.output;
    EXPECT_GT(value, 0) << id << ": " << width.output;
  }
}

TEST_F(StationTest, MbpollReadsTheServedPlc) {
  if (!installed("mbpoll"))
    GTEST_SKIP() << "mbpoll is not installed (apt-get install mbpoll); the check with a third-party Modbus "
                    "client is skipped";
  const int port = basePort();
  ServedCell served(cellFile(work(), port, port + 1), work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  // One poll (-1) of the input registers (-t 3) 0-5 with PDU addressing (-0), unit 1, 1 s timeout.
  const ToolRun poll = runTool("mbpoll -m tcp -a 1 -p " + std::to_string(port + 1) + " -0 -1 -o 1 -t 3 -r 0 -c 6 127.0.0.1");
  ASSERT_EQ(poll.exit_status, 0) << poll.output;
  std::map<int, long> values;  // from lines like "[2]: 	1"
  std::istringstream lines(poll.output);
  std::string line;
  while (std::getline(lines, line)) {
    int reference = 0;
    long value = 0;
    if (std::sscanf(line.c_str(), "[%d]: %ld", &reference, &value) == 2) values[reference] = value;
  }
  ASSERT_EQ(values.size(), 6U) << poll.output;
  EXPECT_EQ(values.at(drivers::plc::address(drivers::plc::InputRegister::FirmwareMajor)), 1) << poll.output;
  EXPECT_EQ(values.at(drivers::plc::address(drivers::plc::InputRegister::FirmwareMinor)), 0) << poll.output;
}

TEST_F(StationTest, RawTcpClientDrivesTheServedCmm) {
  const int port = basePort();
  ServedCell served(cellFile(work(), port, port + 1), work());
  ASSERT_NO_FATAL_FAILURE(served.start());
  LineClient client;
  const std::string connected = client.connect(port);
  ASSERT_EQ(connected, "");
  // Each command is acknowledged (&) and completed (%), data (#) between; lines end in CR LF.
  const auto expectLine = [&client](const std::string& want) {
    const std::optional<std::string> got = client.line();
    ASSERT_TRUE(got.has_value()) << "no reply; expected " << want;
    EXPECT_EQ(*got, want + "\r\n");
  };
  ASSERT_TRUE(client.send("00001 StartSession()\r\n"));
  ASSERT_NO_FATAL_FAILURE(expectLine("00001 &"));
  ASSERT_NO_FATAL_FAILURE(expectLine("00001 %"));

  ASSERT_TRUE(client.send("00002 Get(X(), Y(), Z())\r\n"));
  ASSERT_NO_FATAL_FAILURE(expectLine("00002 &"));
  const std::optional<std::string> data = client.line();
  ASSERT_TRUE(data.has_value()) << "no data for Get";
  double x = -1, y = -1, z = -1;
  ASSERT_EQ(std::sscanf(data->c_str(), "00002 # X(%lf), Y(%lf), Z(%lf)", &x, &y, &z), 3) << *data;
  const std::array<double, 3> power_on = sim::VirtualCmmConfig{}.power_on_position;  // not homed yet
  EXPECT_DOUBLE_EQ(x, power_on[0]) << *data;
  EXPECT_DOUBLE_EQ(y, power_on[1]) << *data;
  EXPECT_DOUBLE_EQ(z, power_on[2]) << *data;
  ASSERT_NO_FATAL_FAILURE(expectLine("00002 %"));

  ASSERT_TRUE(client.send("00003 EndSession()\r\n"));
  ASSERT_NO_FATAL_FAILURE(expectLine("00003 &"));
  ASSERT_NO_FATAL_FAILURE(expectLine("00003 %"));
}

TEST_F(StationTest, DevicesReportsAMissingCell) {
  const int port = basePort() + 2;  // nothing listens here
  const RunResult r = run("devices --cell " + quote(cellFile(work(), port, port + 1)));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("MISSING"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("a required device is missing or faulty"), std::string::npos) << r.out;
}

TEST_F(StationTest, DevicesRejectsABadCellFile) {
  const fs::path bad = work() / "bad.toml";
  writeFile(bad, "[cmm]\nport = \"twelve\"\n");
  RunResult r = run("devices --cell " + quote(bad));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("[cmm] port has the wrong type: expected an integer, found a string"), std::string::npos) << r.err;
  writeFile(bad, "[plc\nport = 1\n");
  r = run("devices --cell " + quote(bad));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("bad.toml:1:"), std::string::npos) << r.err;
  writeFile(bad, "[digitizer]\nvirtual = \"yes\"\n");
  r = run("devices --cell " + quote(bad));
  expectCleanFailure(r, "bad.toml: [digitizer] virtual has the wrong type: expected true or false, found a string");
  EXPECT_EQ(r.out, "");  // refused before anything is probed
  writeFile(bad, "[digitizer]\nvirtual = true\nvendor_id = 0x1234\n");
  r = run("devices --cell " + quote(bad));
  expectCleanFailure(r, "bad.toml: [digitizer] virtual = true, but vendor_id:product_id 1234:61a5 is not the "
                        "virtual digitizer's 1d50:61a5");
}

// The cell file that describes the virtual cell says what the built-in one does.
TEST(StationCells, VirtualCellFileIsTheBuiltInCell) {
  const CellConfig file = loadCellConfig(STAMPSCAN_VIRTUAL_CELL_FILE);
  const CellConfig built_in = virtualCell();
  EXPECT_EQ(file.name, built_in.name);
  EXPECT_EQ(file.cmm.host, built_in.cmm.host);
  EXPECT_EQ(file.cmm.port, built_in.cmm.port);
  EXPECT_EQ(file.plc.host, built_in.plc.host);
  EXPECT_EQ(file.plc.port, built_in.plc.port);
  EXPECT_EQ(file.plc_unit_id, built_in.plc_unit_id);
  EXPECT_EQ(file.left_camera.serial, built_in.left_camera.serial);
  EXPECT_EQ(file.left_camera.address, built_in.left_camera.address);
  EXPECT_EQ(file.right_camera.serial, built_in.right_camera.serial);
  EXPECT_EQ(file.right_camera.address, built_in.right_camera.address);
  EXPECT_EQ(file.digitizer_vendor, built_in.digitizer_vendor);
  EXPECT_EQ(file.digitizer_product, built_in.digitizer_product);
  EXPECT_EQ(file.digitizer_serial, built_in.digitizer_serial);
  EXPECT_TRUE(file.digitizer_virtual);
  EXPECT_TRUE(built_in.digitizer_virtual);
  EXPECT_TRUE(file.digitizer_required);
  EXPECT_TRUE(built_in.digitizer_required);
  EXPECT_EQ(file.cmm_device_time, built_in.cmm_device_time);
  EXPECT_EQ(file.limits.travel_min, built_in.limits.travel_min);
  EXPECT_EQ(file.limits.travel_max, built_in.limits.travel_max);
  EXPECT_EQ(file.limits.min_speed, built_in.limits.min_speed);
  EXPECT_EQ(file.limits.max_speed, built_in.limits.max_speed);
  EXPECT_EQ(file.limits.acceleration, built_in.limits.acceleration);
  EXPECT_NEAR(file.limits.max_tilt, built_in.limits.max_tilt, 1e-12);
  EXPECT_NEAR(file.limits.max_turn, built_in.limits.max_turn, 1e-12);
}

}  // namespace
}  // namespace stampscan::station::test
