#include "stampscan/sim/supervised_cell.hpp"

#include <poll.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>
#include <thread>

namespace stampscan::sim {

// The CMM's head state, shared between the processes of `sim serve`: the CMM's process writes it,
// the cameras' process renders from it. Every field is a lock-free atomic in a MAP_SHARED page, so
// no reader sees a torn number; the sequence number (odd while a write is under way) keeps the five
// numbers of one instant together.
struct SharedHead {
  std::atomic<std::uint64_t> sequence{0};
  std::atomic<double> x{0}, y{0}, z{0}, a{0}, b{0};
  // A replay's time map (CellReplay::shareTimeMap): the CMM's process sets it at every move.
  std::atomic<std::int64_t> replay_offset_ns{0};
  std::atomic<bool> replay_offset_known{false};

  void publish(const VirtualCmmStatus& st) {
    sequence.fetch_add(1);
    x = st.position[0];
    y = st.position[1];
    z = st.position[2];
    a = st.head_a;
    b = st.head_b;
    sequence.fetch_add(1);
  }
  VirtualCmmStatus read() const {
    VirtualCmmStatus st;
    for (;;) {
      const std::uint64_t before = sequence.load();
      if (before % 2 == 1) continue;
      st.position = {x.load(), y.load(), z.load()};
      st.head_a = a.load();
      st.head_b = b.load();
      if (sequence.load() == before) return st;
    }
  }
};
static_assert(std::atomic<double>::is_always_lock_free && std::atomic<std::uint64_t>::is_always_lock_free,
              "the shared head state must be lock-free to live in shared memory");

namespace {


using Device = SupervisedVirtualCell::Device;
using DeviceProcess = SupervisedVirtualCell::DeviceProcess;
const char* deviceName(Device d) { return d == Device::Cmm ? "cmm" : d == Device::Plc ? "plc" : "cameras"; }

void writeAll(int fd, const std::string& text) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n <= 0) return;
    done += static_cast<std::size_t>(n);
  }
}

// The body of one device's process: serves until SIGINT or SIGTERM, then exits. Reports "ready
// PORT" or "error: WHAT" on `report` first.
[[noreturn]] void serveDevice(Device device, VirtualCellOptions options, SharedHead* head, int report,
                              const std::string& replay_trace) {
  options.serve_cmm = device == Device::Cmm;
  options.serve_plc = device == Device::Plc;
  options.cameras = device == Device::Cameras;
  if (device == Device::Cameras) options.head_status = [head] { return head->read(); };
  int code = 0;
  try {
    if (!replay_trace.empty() && device != Device::Plc) {
      // Each process reads the recording itself (a fork copies no thread, and the file is read once
      // per device that serves it).
      options.replay = std::make_shared<CellReplay>(loadRecordedSession(replay_trace));
      options.replay->shareTimeMap(&head->replay_offset_ns, &head->replay_offset_known);
    }
    VirtualCell cell(options);
    cell.start();
    std::atomic<bool> stopping{false};
    std::thread publisher;
    if (device == Device::Cmm) {
      // 1 kHz: a camera frame is rendered from a pose at most a millisecond old.
      publisher = std::thread([&] {
        while (!stopping) {
          head->publish(cell.cmm().status());
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
      });
    }
    const int port = device == Device::Cmm ? cell.cmm().port() : device == Device::Plc ? cell.plc().port() : 3956;
    writeAll(report, "ready " + std::to_string(port) + "\n");
    ::close(report);
    sigset_t stop;
    sigemptyset(&stop);
    sigaddset(&stop, SIGINT);
    sigaddset(&stop, SIGTERM);
    int signal_number = 0;
    sigwait(&stop, &signal_number);
    stopping = true;
    if (publisher.joinable()) publisher.join();
    cell.stop();
  } catch (const std::exception& e) {
    writeAll(report, std::string("error: ") + e.what() + "\n");
    code = 1;
  }
  std::fflush(stdout);
  ::_exit(code);
}

// Forks the device's process and waits (up to 20 s, 120 s for a replay) for it to say it serves. Throws naming the
// device with its own error when it cannot.
DeviceProcess startDevice(Device device, const VirtualCellOptions& options, SharedHead* head,
                          const std::string& replay_trace) {
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error(std::string("cannot start the ") + deviceName(device) + ": pipe failed");
  std::fflush(stdout);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(std::string("cannot start the ") + deviceName(device) + ": fork failed");
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);  // a device never outlives its supervisor
    ::close(fds[0]);
    serveDevice(device, options, head, fds[1], replay_trace);
  }
  ::close(fds[1]);
  std::string reply;
  // A replay reads its recording first, which may take a while for a long session.
  const auto limit = std::chrono::seconds(replay_trace.empty() ? 20 : 120);
  const auto deadline = std::chrono::steady_clock::now() + limit;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd p{fds[0], POLLIN, 0};
    if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
    char buffer[512];
    const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
    if (n <= 0) break;
    reply.append(buffer, static_cast<std::size_t>(n));
    if (reply.find('\n') != std::string::npos) break;
  }
  ::close(fds[0]);
  if (reply.rfind("ready ", 0) == 0) return {device, pid, std::atoi(reply.c_str() + 6)};
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
  while (!reply.empty() && reply.back() == '\n') reply.pop_back();
  if (reply.rfind("error: ", 0) == 0) reply = reply.substr(7);
  throw std::runtime_error(std::string("the virtual ") + deviceName(device) + " did not start: " +
                           (reply.empty() ? "no answer within " + std::to_string(limit.count()) + " s" : reply));
}

void stopDevices(std::vector<DeviceProcess>& devices) {
  for (const DeviceProcess& d : devices) ::kill(d.pid, SIGTERM);
  for (const DeviceProcess& d : devices) {
    // A device that does not stop within 5 s is killed.
    int status = 0;
    for (int waited = 0; waited < 100 && ::waitpid(d.pid, &status, WNOHANG) == 0; ++waited)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (::waitpid(d.pid, &status, WNOHANG) == 0) {
      ::kill(d.pid, SIGKILL);
      ::waitpid(d.pid, &status, 0);
    }
  }
  devices.clear();
}


}  // namespace

SupervisedVirtualCell::SupervisedVirtualCell(VirtualCellOptions options, std::string replay_trace)
    : options_(std::move(options)), replay_trace_(std::move(replay_trace)) {
  // One shared page for the head state, and every device's process forked before this process
  // starts any thread.
  void* page = ::mmap(nullptr, sizeof(SharedHead), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (page == MAP_FAILED) throw std::runtime_error("cannot map the shared head state");
  head_ = new (page) SharedHead();
  try {
    for (const Device d : {Device::Cmm, Device::Plc, Device::Cameras})
      devices_.push_back(startDevice(d, options_, head_, replay_trace_));
  } catch (...) {
    stopDevices(devices_);
    ::munmap(head_, sizeof(SharedHead));
    throw;
  }
  cmm_port_ = devices_[0].port;
  plc_port_ = devices_[1].port;
}

SupervisedVirtualCell::~SupervisedVirtualCell() {
  stopDevices(devices_);
  ::munmap(head_, sizeof(SharedHead));
}

void SupervisedVirtualCell::restartStopped(const std::function<void(const std::string& line)>& log) {
  char line[512];
  for (DeviceProcess& d : devices_) {
    int status = 0;
    if (::waitpid(d.pid, &status, WNOHANG) != d.pid) continue;
    const std::string how = WIFSIGNALED(status) ? std::string("killed by signal ") + std::to_string(WTERMSIG(status)) + " (" +
                                                      strsignal(WTERMSIG(status)) + ")"
                                                : "exit " + std::to_string(WEXITSTATUS(status));
    std::snprintf(line, sizeof line, "%-11s stopped unexpectedly (%s); the other devices go on; starting it again",
                  deviceName(d.device), how.c_str());
    log(line);
    try {
      d = startDevice(d.device, options_, head_, replay_trace_);
      std::snprintf(line, sizeof line, "%-11s serving again", deviceName(d.device));
    } catch (const std::exception& e) {
      std::snprintf(line, sizeof line, "%-11s %s", deviceName(d.device), e.what());
      d.pid = -1;
    }
    log(line);
  }
  std::erase_if(devices_, [](const DeviceProcess& d) { return d.pid < 0; });
}

}  // namespace stampscan::sim
