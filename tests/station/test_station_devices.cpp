// `station sim serve` and `station devices`: the virtual cell on loopback, found and checked through
// the real drivers, with the virtual digitizer hosted in the devices command's own process; the
// served devices also answer independent tools (arv-tool, mbpoll, a plain TCP client speaking
// I++ DME); missing devices and bad cell files give clear reports and a non-zero exit.
#include "served_cell_support.hpp"

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
  EXPECT_EQ(values.at(drivers::plc::RegisterMap::standard().address(drivers::plc::InputRegister::FirmwareMajor)), 1) << poll.output;
  EXPECT_EQ(values.at(drivers::plc::RegisterMap::standard().address(drivers::plc::InputRegister::FirmwareMinor)), 0) << poll.output;
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

// The cell file that describes the virtual cell is the built-in one (compiled in), key for key.
TEST(StationCells, VirtualCellFileIsTheBuiltInCell) {
  CellConfig file = loadCellConfig(STAMPSCAN_VIRTUAL_CELL_FILE);
  const CellConfig built_in = virtualCell();
  file.source = built_in.source;
  file.defaulted.clear();
  EXPECT_EQ(acquisition::describeCellConfig(file), acquisition::describeCellConfig(built_in));
  EXPECT_EQ(file.geometry, built_in.geometry);
  EXPECT_TRUE(built_in.digitizer_virtual);
  EXPECT_TRUE(built_in.cmm_device_time);
  EXPECT_TRUE(built_in.plc_line_start);  // the line's PLC may start scans on the virtual cell
  ASSERT_TRUE(built_in.geometry.ball_bar.has_value());
}

// [calibration]: the rules a cell's file sets, and a bad value named with its section and key.
TEST(StationCells, CalibrationRulesAreReadAndBadOnesNamed) {
  const fs::path dir = fs::temp_directory_path() / ("stampscan_cell_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path file = dir / "cell.toml";
  writeFile(file, "name = \"line 3\"\n[calibration]\ndir = \"/var/cal\"\nvalidity_days = 2.5\nform_mpe_mm = 0.02\n"
                  "[sphere]\ndiameter_mm = 30.0\n");
  const CellConfig c = loadCellConfig(file);
  EXPECT_EQ(c.calibration.dir, "/var/cal");
  EXPECT_DOUBLE_EQ(c.calibration.validity_days, 2.5);
  EXPECT_DOUBLE_EQ(c.calibration.form_mpe_mm, 0.02);
  EXPECT_DOUBLE_EQ(c.geometry.sphere.diameter_mm, 30.0);
  EXPECT_DOUBLE_EQ(c.calibration.size_mpe_mm, acquisition::CalibrationPolicy{}.size_mpe_mm);  // the default
  for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
           {"[calibration]\nvalidity_days = 0\n", "[calibration] validity_days must be a positive number"},
           {"[calibration]\nform_mpe_mm = \"tight\"\n", "[calibration] form_mpe_mm must be a positive number"},
           {"[calibration]\ndir = 3\n", "[calibration] dir has the wrong type"},
           {"[sphere]\ndiameter_mm = -1\n", "[sphere] diameter_mm must be a positive number"},
           {"[calibration]\nsphere_diameter_mm = 25.4\n", "[calibration] sphere_diameter_mm has moved: write it as [sphere] diameter_mm"},
           {"calibration = 5\n", "[calibration] must be a table"}}) {
    writeFile(file, text);
    try {
      (void)loadCellConfig(file);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace stampscan::station::test
