// Shared by the panel's tests: `station hmi` started as its own process on the embedded virtual
// cell (as an operator starts it), on a free port, with a scratch runs folder; an HTTP client for it.
#pragma once

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <thread>
#include <vector>

#ifndef STATION_EXE
#error "STATION_EXE must name the station executable"
#endif

namespace stampscan::hmi::test {

namespace fs = std::filesystem;
using nlohmann::json;

inline std::string readText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// What a shell command prints on its standard output.
inline std::string outputOf(const std::string& command) {
  FILE* pipe = popen(command.c_str(), "r");
  std::string out;
  char buffer[4096];
  while (pipe != nullptr && fgets(buffer, sizeof buffer, pipe) != nullptr) out += buffer;
  if (pipe != nullptr) pclose(pipe);
  return out;
}

// The password's hash as `station hmi --hash-password` prints it.
inline std::string hashOf(const std::string& password) {
  std::string out = outputOf("echo " + password + " | " STATION_EXE " hmi --hash-password");
  while (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

// A request whose connection the panel closes (a refused body) must fail the request, not kill the
// test process with SIGPIPE (which would leave its panel running).
inline const bool kSigpipeIgnored = [] {
  std::signal(SIGPIPE, SIG_IGN);
  return true;
}();

// Sends `request` whole on a new connection to 127.0.0.1:port and returns what comes back until the
// server closes (or 5 s pass).
inline std::string rawExchange(int port, const std::string& request) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return "";
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string reply;
  timeval timeout{5, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0 &&
      ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(request.size())) {
    char buffer[4096];
    for (ssize_t n; (n = ::recv(fd, buffer, sizeof buffer, 0)) > 0;) reply.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return reply;
}

// Runs `station hmi ARGS --ready-file ... -o ROOT/runs` until destroyed.
class StationHmi {
 public:
  StationHmi(const fs::path& root, std::vector<std::string> args) : root_(root) {
    ready_ = root / "ready.txt";
    fs::remove(ready_);
    args.insert(args.begin(), {STATION_EXE, "hmi"});
    for (const char* a : {"--ready-file", ready_.c_str(), "-o"}) args.emplace_back(a);
    args.push_back((root / "runs").string());
    std::fflush(nullptr);  // what this process has buffered is written once, not again by the child
    pid_ = fork();
    if (pid_ == 0) {
      // The panel goes with the test: a test process that dies (a crash, a signal) must not leave
      // it holding the virtual cell's ports for the tests after it.
      prctl(PR_SET_PDEATHSIG, SIGTERM);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      const std::string log = (root / "station.log").string();
      freopen(log.c_str(), "w", stdout);
      freopen(log.c_str(), "a", stderr);
      execv(STATION_EXE, argv.data());
      _exit(127);
    }
  }
  ~StationHmi() { stop(); }
  // The port once it serves (0 when it exited first; exit_code then says how).
  int waitReady() {
    for (int i = 0; i < 600; ++i) {
      const std::string url = readText(ready_);
      if (!url.empty() && url.back() == '\n') {
        port_ = std::stoi(url.substr(url.rfind(':') + 1));
        return port_;
      }
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        pid_ = -1;
        return 0;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return 0;
  }
  // SIGTERM (as systemd stops the panel's service), then waits; exit_code then says how it ended.
  void stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
    exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    pid_ = -1;
  }
  std::string log() const { return readText(root_ / "station.log"); }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  int exit_code = -1;

 private:
  fs::path root_, ready_;
  pid_t pid_ = -1;
  int port_ = 0;
};

// A run folder as `station scan` leaves it, made by hand for the analysis views: run.json,
// cloud4d.ply (a 10 x 8 grid of elements at the 2.54 mm pitch on the slope z = 0.1 x, uniform
// strains, major direction x) and mesh.ply (a triangulated plate over the grid).
inline void writeSyntheticRun(const fs::path& dir, const std::string& part_id, const std::string& program,
                              double thickness_strain, double shift_x_mm) {
  fs::create_directories(dir);
  std::ofstream(dir / "run.json") << json{{"part_id", part_id}, {"program", program}}.dump();
  std::ofstream cloud(dir / "cloud4d.ply");
  cloud << "ply\nformat ascii 1.0\nelement vertex 80\n";
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "strain", "major_strain", "minor_strain", "major_dir_x",
                        "major_dir_y", "major_dir_z"})
    cloud << "property float " << p << "\n";
  cloud << "end_header\n";
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 8; ++j) {
      const double x = i * 2.54 + shift_x_mm;
      cloud << x << ' ' << j * 2.54 << ' ' << 0.1 * x << " 0 0 1 " << thickness_strain << " 0.04 0.01 1 0 0\n";
    }
  std::ofstream mesh(dir / "mesh.ply");
  mesh << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
          "property float strain\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
  mesh << "0 0 0 " << thickness_strain << "\n22.86 0 2.286 " << thickness_strain << "\n22.86 17.78 2.286 "
       << thickness_strain << "\n0 17.78 0 " << thickness_strain << "\n3 0 1 2\n3 0 2 3\n";
}

class HmiTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device device;
    root_ = fs::temp_directory_path() / ("stampscan_hmi_test_" + std::to_string(device()) + std::to_string(device()));
    fs::create_directories(root_ / "runs");
  }
  void TearDown() override {
    station_.reset();
    std::error_code ignored;
    fs::remove_all(root_, ignored);
  }
  // Starts the panel and a client for it; fails the test when it does not serve.
  void startPanel(std::vector<std::string> args = {"--listen", "127.0.0.1:0"}) {
    station_ = std::make_unique<StationHmi>(root_, std::move(args));
    ASSERT_GT(station_->waitReady(), 0) << station_->log();
    client_ = std::make_unique<httplib::Client>("127.0.0.1", station_->port());
    client_->set_read_timeout(30, 0);
    client_->set_url_encode(false);  // the tests send their paths exactly as written
  }
  // The JSON body of a response (null when it is not JSON).
  static json body(const httplib::Result& r) { return r ? json::parse(r->body, nullptr, false) : json(); }
  std::string csrf() { return body(client_->Get("/api/session"))["csrf"].get<std::string>(); }
  httplib::Result post(const std::string& path, const std::string& payload, const std::string& token,
                       httplib::Headers headers = {}) {
    if (!token.empty()) headers.emplace("X-CSRF-Token", token);
    return client_->Post(path.c_str(), headers, payload, "application/json");
  }

  fs::path root_;
  std::unique_ptr<StationHmi> station_;
  std::unique_ptr<httplib::Client> client_;
};

}  // namespace stampscan::hmi::test
