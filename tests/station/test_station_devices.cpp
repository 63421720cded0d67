// `station sim serve` and `station devices`: the virtual cell on loopback, found and checked through
// the real drivers; missing devices and bad cell files give clear reports and a non-zero exit.
#include "station_test_support.hpp"

#include <chrono>
#include <thread>
#include <csignal>
#include <sys/types.h>
#include <unistd.h>

namespace stampscan::station::test {
namespace {

// A cell file on ports of its own, so that tests running in parallel do not collide.
fs::path cellFile(const fs::path& dir, int cmm_port, int plc_port) {
  const fs::path file = dir / "cell.toml";
  writeFile(file, "name = \"test cell\"\n[cmm]\nhost = \"127.0.0.1\"\nport = " + std::to_string(cmm_port) +
                      "\n[plc]\nhost = \"127.0.0.1\"\nport = " + std::to_string(plc_port) +
                      "\n[digitizer]\nrequired = false\n");
  return file;
}

int basePort() { return 20000 + static_cast<int>(getpid() % 20000); }

TEST_F(StationTest, DevicesFindsTheServedVirtualCell) {
  const int port = basePort();
  const fs::path cell = cellFile(work(), port, port + 1);
  // Serve in the background; stopped (SIGTERM, then waited for) before the test ends, so that the
  // fake cameras have left UDP 3956 when the next camera test starts.
  const fs::path pid_file = work() / "serve.pid";
  const std::string serve = "sh -c 'echo $$ > " + pid_file.string() + "; exec " + std::string(STATION_EXE) +
                            " sim serve --for 30 --cell " + cell.string() + "' >" + quote(work() / "serve.txt") + " 2>&1 &";
  ASSERT_EQ(std::system(serve.c_str()), 0);
  pid_t server = 0;
  for (int attempt = 0; attempt < 50 && server == 0; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const std::string text = readFile(pid_file);
    if (!text.empty() && text.back() == '\n') server = static_cast<pid_t>(std::stol(text));
  }
  ASSERT_GT(server, 0);
  struct StopServer {
    pid_t pid;
    ~StopServer() {
      ::kill(pid, SIGTERM);
      for (int i = 0; i < 100 && ::kill(pid, 0) == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  } stop_server{server};
  RunResult r;
  for (int attempt = 0; attempt < 50; ++attempt) {  // until the servers listen
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
  EXPECT_NE(r.out.find("all required devices answered"), std::string::npos) << r.out;
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
  EXPECT_NE(r.err.find("[cmm] port has the wrong type"), std::string::npos) << r.err;
  writeFile(bad, "[plc\nport = 1\n");
  r = run("devices --cell " + quote(bad));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("bad.toml:1:"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace stampscan::station::test
