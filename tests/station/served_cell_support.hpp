// Shared by the tests that serve the virtual cell with `station sim serve` and talk to it over the
// network: cell files on ports of their own, the served cell as an object, a plain line client and
// a way to run other programs.
#pragma once

#include "station_test_support.hpp"

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
#include <optional>
#include <string>
#include <thread>

namespace stampscan::station::test {

// The [digitizer] section of a cell whose digitizer is the virtual one, hosted by `station devices`.
constexpr const char* kVirtualDigitizer = "virtual = true\nrequired = true\n";
// ... and of a cell that lets the digitizer be absent (no virtual key: a real USB device).
constexpr const char* kOptionalDigitizer = "required = false\n";

// A cell file on ports of its own, so that tests running in parallel do not collide; the cameras
// are the defaults (STAMPSCAN-LEFT on 127.0.0.1, STAMPSCAN-RIGHT on 127.0.0.2).
inline fs::path cellFile(const fs::path& dir, int cmm_port, int plc_port, const std::string& digitizer = kOptionalDigitizer,
                  const std::string& name = "cell.toml") {
  const fs::path file = dir / name;
  writeFile(file, "name = \"test cell\"\n[cmm]\nhost = \"127.0.0.1\"\nport = " + std::to_string(cmm_port) +
                      "\n[plc]\nhost = \"127.0.0.1\"\nport = " + std::to_string(plc_port) + "\n[digitizer]\n" + digitizer);
  return file;
}

inline int basePort() { return 20000 + static_cast<int>(getpid() % 20000); }

// The Aravis device ids of the served fake cameras: "Aravis-Fake-<serial>".
constexpr const char* kLeftCameraId = "Aravis-Fake-STAMPSCAN-LEFT";
constexpr const char* kRightCameraId = "Aravis-Fake-STAMPSCAN-RIGHT";

// `station sim serve --for 300 --cell CELL` in the background, from start() until this object goes
// away: then SIGTERM, waited for, so that the fake cameras have left UDP 3956 when the next camera
// test starts. The tests that serve take the cameras' lock (station_test_lock.cmake).
class ServedCell {
 public:
  // `shell_prefix` runs before the server in its shell (e.g. "ulimit -n 128; ").
  ServedCell(fs::path cell, fs::path dir, std::string shell_prefix = "")
      : cell_(std::move(cell)), dir_(std::move(dir)), prefix_(std::move(shell_prefix)) {}
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
    const std::string serve = "sh -c 'echo $$ > " + pid_file.string() + "; " + prefix_ + "exec " + std::string(STATION_EXE) +
                              " sim serve --for 300 --cell " + cell_.string() + "' >" + quote(log()) + " 2>&1 &";
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
  std::string prefix_;
  pid_t pid_ = 0;
};

// A program's output (stdout and stderr) and exit status, through /bin/sh; -1 when it could not run.
struct ToolRun {
  int exit_status = -1;
  std::string output;
};

inline ToolRun runTool(const std::string& command) {
  ToolRun r;
  std::FILE* pipe = ::popen(("timeout 20 " + command + " 2>&1 </dev/null").c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 512> buffer{};
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) r.output += buffer.data();
  const int status = ::pclose(pipe);
  r.exit_status = status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

inline bool installed(const std::string& program) {
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

}  // namespace stampscan::station::test
