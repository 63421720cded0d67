// The installed station as systemd runs it: the panel's unit (station/packaging/stampscan-panel.service)
// passes `systemd-analyze verify`, and its own command line, with the paths of a scratch cell, starts
// the panel, whose log carries the journal's levels, and its stop signal ends it cleanly within the
// unit's stop timeout.
#include "station_test_support.hpp"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <map>
#include <sstream>
#include <thread>

namespace stampscan::station::test {
namespace {

const fs::path kUnit = fs::path(STAMPSCAN_PACKAGING_DIR) / "stampscan-panel.service";

// The unit's [Service] keys (the last value of each).
std::map<std::string, std::string> serviceKeys(const std::string& unit) {
  std::map<std::string, std::string> keys;
  std::istringstream lines(unit);
  bool service = false;
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty() && line.front() == '[') service = line == "[Service]";
    const auto equals = line.find('=');
    if (service && equals != std::string::npos && line.front() != '#') keys[line.substr(0, equals)] = line.substr(equals + 1);
  }
  return keys;
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  for (auto at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) text.replace(at, from.size(), to);
  return text;
}

std::string findProgram(const char* name) {
  for (const char* dir : {"/usr/bin", "/bin", "/usr/sbin"})
    if (fs::exists(fs::path(dir) / name)) return (fs::path(dir) / name).string();
  return "";
}

TEST_F(StationTest, ThePanelsServiceUnitPassesSystemdsCheck) {
  const std::string analyze = findProgram("systemd-analyze");
  if (analyze.empty()) GTEST_SKIP() << "systemd-analyze is not installed (scripts/setup.sh installs systemd)";
  // The unit as installed, but with this build's program (verify checks that ExecStart's exists).
  const fs::path unit = work() / "stampscan-panel.service";
  writeFile(unit, replaced(readFile(kUnit), "/usr/bin/station", STATION_EXE));
  const std::string out = work().string() + "/verify.txt";
  const int status = std::system((analyze + " verify --man=no " + quote(unit) + " >" + quote(out) + " 2>&1").c_str());
  EXPECT_EQ(status, 0) << readFile(out);
  EXPECT_EQ(readFile(out), "") << "systemd-analyze has remarks";
}

TEST_F(StationTest, ThePanelsServiceStartsFromItsCommandLineAndItsStopSignalEndsIt) {
  const std::map<std::string, std::string> keys = serviceKeys(readFile(kUnit));
  EXPECT_EQ(keys.at("Restart"), "on-failure");
  EXPECT_EQ(keys.at("User"), "stampscan");
  ASSERT_EQ(keys.at("KillSignal"), "SIGTERM");
  const int stop_timeout = std::stoi(keys.at("TimeoutStopSec"));
  // A cell whose devices are nowhere and whose results database is damaged: the panel serves, and
  // its health's fault goes into the log with the journal's level for an error.
  const fs::path cell = work() / "cell.toml", runs = work() / "runs", ready = work() / "ready.txt", log = work() / "log.txt";
  writeFile(cell, "name = \"service test cell\"\n[cmm]\nport = 9\n[plc]\nport = 9\n[cameras]\nleft_address = \"127.0.0.3\"\n"
                  "right_address = \"127.0.0.4\"\n[hmi]\nlisten = \"127.0.0.1:0\"\n");
  fs::create_directories(runs);
  writeFile(runs / "results.sqlite", "not a database");
  std::string command = keys.at("ExecStart");
  command = replaced(command, "/usr/bin/station", quote(std::string(STATION_EXE)));
  command = replaced(command, "/etc/stampscan/cell.toml", quote(cell));
  command = replaced(command, "/var/lib/stampscan/runs", quote(runs));
  ASSERT_EQ(command.find("/usr/"), std::string::npos) << command;
  command += " --ready-file " + quote(ready);
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGTERM);  // the panel goes with the test, whatever ends it
    setenv("JOURNAL_STREAM", "8:4242", 1);  // as systemd sets it for a service logging to the journal
    execl("/bin/sh", "sh", "-c", ("exec " + command + " >" + quote(log) + " 2>&1").c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  for (int i = 0; i < 300 && readFile(ready).empty(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_NE(readFile(ready).find("http://127.0.0.1:"), std::string::npos) << readFile(log);
  for (int i = 0; i < 200 && readFile(log).find("<3>station hmi: fault: the results database") == std::string::npos; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_NE(readFile(log).find("<3>station hmi: fault: the results database cannot be read"), std::string::npos)
      << readFile(log);

  // systemd's stop: the KillSignal, then SIGKILL after TimeoutStopSec.
  const auto start = std::chrono::steady_clock::now();
  kill(pid, SIGTERM);
  int status = 0;
  pid_t ended = 0;
  while ((ended = waitpid(pid, &status, WNOHANG)) == 0 &&
         std::chrono::steady_clock::now() - start < std::chrono::seconds(stop_timeout))
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (ended == 0) {
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    FAIL() << "the panel did not stop within the unit's " << stop_timeout << " s:\n" << readFile(log);
  }
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status << "\n" << readFile(log);
  EXPECT_LT(seconds, 5.0);
  EXPECT_NE(readFile(log).find("station hmi: stopped"), std::string::npos) << readFile(log);
}

}  // namespace
}  // namespace stampscan::station::test
