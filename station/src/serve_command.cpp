// `station sim serve [--cell CELL.toml] [--part pan|dome] [--for SECONDS]`: runs the virtual cell
// (one simulated world, sim/virtual_cell) with its devices on their real protocols until
// interrupted, so that the station and independent tools (mbpoll, arv-tool, a plain TCP client
// speaking I++ DME) can talk to them. Loopback only unless the cell file says
// otherwise. The virtual digitizer is not among them: see virtual_digitizer_host.hpp.
//
// Each device runs in a process of its own (the CMM, the PLC, the two cameras), so that a fault in
// one cannot take the others down; this process supervises them and starts again one that stops
// unexpectedly. They build the same world from the same seed; the cameras render from the head
// pose that the CMM's process publishes in a shared page.
#include "stampscan/sim/virtual_cell.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/station/commands.hpp"

#include <poll.h>
#include <sys/prctl.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace stampscan::station {

namespace {

// The CMM's head state, shared between the processes of `sim serve`: the CMM's process writes it,
// the cameras' process renders from it. Every field is a lock-free atomic in a MAP_SHARED page, so
// no reader sees a torn number; the sequence number (odd while a write is under way) keeps the five
// numbers of one instant together.
struct SharedHead {
  std::atomic<std::uint64_t> sequence{0};
  std::atomic<double> x{0}, y{0}, z{0}, a{0}, b{0};
  // A replay's time map (sim::CellReplay::shareTimeMap): the CMM's process sets it at every move.
  std::atomic<std::int64_t> replay_offset_ns{0};
  std::atomic<bool> replay_offset_known{false};

  void publish(const sim::VirtualCmmStatus& st) {
    sequence.fetch_add(1);
    x = st.position[0];
    y = st.position[1];
    z = st.position[2];
    a = st.head_a;
    b = st.head_b;
    sequence.fetch_add(1);
  }
  sim::VirtualCmmStatus read() const {
    sim::VirtualCmmStatus st;
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

enum class Device { Cmm, Plc, Cameras };
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
[[noreturn]] void serveDevice(Device device, sim::VirtualCellOptions options, SharedHead* head, int report,
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
      options.replay = std::make_shared<sim::CellReplay>(sim::loadRecordedSession(replay_trace));
      options.replay->shareTimeMap(&head->replay_offset_ns, &head->replay_offset_known);
    }
    sim::VirtualCell cell(options);
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

struct DeviceProcess {
  Device device;
  pid_t pid = -1;
  int port = 0;
};

// Forks the device's process and waits (up to 20 s, 120 s for a replay) for it to say it serves. Throws naming the
// device with its own error when it cannot.
DeviceProcess startDevice(Device device, const sim::VirtualCellOptions& options, SharedHead* head,
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


using acquisition::CellConfig;
using acquisition::loadCellConfig;
using acquisition::virtualCell;

CommandRunner addServeSubcommand(CLI::App* sim) {
  struct Options {
    std::string cell, part = "pan", replay;
    double seconds = 0;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* cmd = sim->add_subcommand("serve", "Run the virtual cell (CMM over I++ DME, PLC over Modbus TCP, GigE Vision cameras) until interrupted");
  cmd->add_option("--cell", opt->cell, "Cell configuration (TOML); default: the built-in virtual cell");
  cmd->add_option("--part", opt->part, "The part on the fixture of the simulated world")->check(CLI::IsMember({"pan", "dome"}));
  cmd->add_option("--replay", opt->replay,
                  "Serve a recorded trace instead of the simulated world: the CMM follows its head track, the "
                  "cameras serve its frames (the digitizer is hosted by the command that scans)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--for", opt->seconds, "Stop after this many seconds (default: run until Ctrl-C)")->check(CLI::PositiveNumber);
  return [opt]() {
    const CellConfig cell = opt->cell.empty() ? virtualCell() : loadCellConfig(opt->cell);
    // Block the stop signals before any device thread starts, so that only sigtimedwait sees them.
    sigset_t stop;
    sigemptyset(&stop);
    sigaddset(&stop, SIGINT);
    sigaddset(&stop, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop, nullptr);

    // The virtual cell as one world (sim/virtual_cell): the cameras render the part, sphere and
    // plate from the head pose the CMM has, whoever moves it. The second camera address is added
    // to lo when missing, which needs root.
    sim::VirtualCellOptions world;
    world.world = sim::ScanParams::quick();
    world.world.part = opt->part == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan;
    world.cmm_address = cell.cmm.host;
    world.cmm_port = static_cast<std::uint16_t>(cell.cmm.port);
    world.plc_address = cell.plc.host;
    world.plc_port = cell.plc.port;
    world.cameras = true;
    world.left_address = cell.left_camera.address;
    world.left_serial = cell.left_camera.serial;
    world.right_address = cell.right_camera.address;
    world.right_serial = cell.right_camera.serial;
    // One shared page for the head state, and every device's process forked before this process
    // starts any thread (a fork copies only the calling thread).
    void* page = ::mmap(nullptr, sizeof(SharedHead), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    if (page == MAP_FAILED) throw std::runtime_error("cannot map the shared head state");
    SharedHead* head = new (page) SharedHead();
    std::vector<DeviceProcess> devices;
    try {
      for (const Device d : {Device::Cmm, Device::Plc, Device::Cameras}) devices.push_back(startDevice(d, world, head, opt->replay));
    } catch (...) {
      stopDevices(devices);
      throw;
    }
    const int cmm_port = devices[0].port, plc_port = devices[1].port;
    std::printf("station sim serve: %s (each device in a process of its own)%s\n", cell.name.c_str(),
                opt->replay.empty() ? "" : (", replaying " + opt->replay).c_str());
    std::printf("  cmm         I++ DME on %s:%d   (try: printf '00001 StartSession()\\r\\n' | nc %s %d)\n",
                cell.cmm.host.c_str(), cmm_port, cell.cmm.host.c_str(), cmm_port);
    std::printf("  plc         Modbus TCP on %s:%d   (try: mbpoll -m tcp -a 1 -t 1 -r 1 -c 6 -1 -p %d %s)\n",
                cell.plc.host.c_str(), plc_port, plc_port, cell.plc.host.c_str());
    std::printf("  cameras     GigE Vision %s on %s, %s on %s   (try: arv-tool-0.8)\n",
                cell.left_camera.serial.c_str(), cell.left_camera.address.c_str(), cell.right_camera.serial.c_str(),
                cell.right_camera.address.c_str());
    // The virtual digitizer is a USB device under umockdev: it exists only inside the process that
    // hosts it, so it cannot be served to others from here.
    if (cell.digitizer_virtual)
      std::printf("  digitizer   not served here: a USB device under umockdev, hosted in-process by `station devices`"
                  " (see sim/virtual_digitizer)\n");
    else
      std::printf("  digitizer   not served: this cell's digitizer is a USB device (%04x:%04x), not virtual\n",
                  cell.digitizer_vendor, cell.digitizer_product);
    std::printf("  running; Ctrl-C stops%s\n", opt->seconds > 0 ? " (or the --for time)" : "");
    std::fflush(stdout);
    // Until a signal or the --for time; a device that stops unexpectedly is started again (a
    // fault in one device must not take the cell down).
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(opt->seconds > 0 ? opt->seconds : 3.15e7);
    const char* why = "time up";
    while (std::chrono::steady_clock::now() < until) {
      timespec slice{0, 200'000'000};
      if (sigtimedwait(&stop, nullptr, &slice) > 0) {
        why = "signal";
        break;
      }
      for (DeviceProcess& d : devices) {
        int status = 0;
        if (::waitpid(d.pid, &status, WNOHANG) != d.pid) continue;
        const std::string how = WIFSIGNALED(status) ? std::string("killed by signal ") + std::to_string(WTERMSIG(status)) + " (" +
                                                          strsignal(WTERMSIG(status)) + ")"
                                                    : "exit " + std::to_string(WEXITSTATUS(status));
        std::printf("  %-11s stopped unexpectedly (%s); the other devices go on; starting it again\n", deviceName(d.device),
                    how.c_str());
        std::fflush(stdout);
        try {
          d = startDevice(d.device, world, head, opt->replay);
          std::printf("  %-11s serving again\n", deviceName(d.device));
        } catch (const std::exception& e) {
          std::printf("  %-11s %s\n", deviceName(d.device), e.what());
          d.pid = -1;
        }
        std::fflush(stdout);
      }
      std::erase_if(devices, [](const DeviceProcess& d) { return d.pid < 0; });
    }
    std::printf("  stopping (%s)\n", why);
    stopDevices(devices);
    ::munmap(page, sizeof(SharedHead));
    return 0;
  };
}

}  // namespace stampscan::station
