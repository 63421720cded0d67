#include "virtual_digitizer_host.hpp"

#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/visibility.hpp"

#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::station {

using acquisition::CellConfig;
using acquisition::loadCellConfig;
using acquisition::virtualCell;

namespace {

// Set for the re-executed process, so that it reports the failure instead of re-executing again.
constexpr const char* kReexecMarker = "STAMPSCAN_UMOCKDEV_REEXEC";

// This program's arguments as it was started (NUL-separated in /proc/self/cmdline).
std::vector<std::string> ownArguments() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  std::vector<std::string> args;
  for (std::string::size_type start = 0; start < bytes.size();) {
    const std::string::size_type end = std::min(bytes.find('\0', start), bytes.size());
    args.push_back(bytes.substr(start, end - start));
    start = end + 1;
  }
  if (args.empty()) throw std::runtime_error("virtual digitizer: /proc/self/cmdline is unreadable or empty");
  return args;
}

bool isAsanRuntime(const std::string& file) {
  return file.find("libasan.so") != std::string::npos || file.find("libclang_rt.asan") != std::string::npos;
}

// The ASan runtime this process has mapped (a sanitizer build linked against the shared runtime), or "".
std::string mappedAsanRuntime() {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line)) {
    const std::string::size_type path = line.find('/');
    if (path != std::string::npos && isAsanRuntime(line.substr(path))) return line.substr(path);
  }
  return "";
}

// LD_PRELOAD with umockdev's library added, first as umockdev-wrapper puts it, except after an ASan
// runtime: ASan checks that it comes before every other library and aborts otherwise, so a
// preloaded runtime stays first, and a linked one is preloaded first (the same file, loaded once).
std::string preloadWithUmockdev(const char* current) {
  std::vector<std::string> entries;  // the dynamic loader splits the list at colons and spaces
  std::string entry;
  for (const char* p = current != nullptr ? current : "";; ++p) {
    if (*p != ':' && *p != ' ' && *p != '\0') {
      entry += *p;
      continue;
    }
    if (!entry.empty()) entries.push_back(entry);
    entry.clear();
    if (*p == '\0') break;
  }
  std::vector<std::string> ordered;
  if (const auto asan = std::find_if(entries.begin(), entries.end(), isAsanRuntime); asan != entries.end()) {
    ordered.push_back(*asan);
    entries.erase(asan);
  } else if (const std::string linked = mappedAsanRuntime(); !linked.empty()) {
    ordered.push_back(linked);
  }
  ordered.push_back(kUmockdevPreload);
  ordered.insert(ordered.end(), entries.begin(), entries.end());
  std::string joined;
  for (const std::string& e : ordered) joined += (joined.empty() ? "" : ":") + e;
  return joined;
}

}  // namespace

void requireUmockdevPreload() {
  if (sim::VirtualDigitizer::preloadActive()) {
    ::unsetenv(kReexecMarker);  // not inherited by anything this process starts
    return;
  }
  const char* preload = std::getenv("LD_PRELOAD");
  if (std::getenv(kReexecMarker) != nullptr) {
    throw std::runtime_error(std::string("virtual digitizer: ") + kUmockdevPreload +
                             " is not loaded although this program was re-executed with LD_PRELOAD=" +
                             (preload != nullptr ? preload : "") + " (is umockdev installed? apt-get install umockdev)");
  }
  // Load it here first: when it is missing, this says so and how to install it, instead of the new
  // process starting without it after a warning from the dynamic loader.
  void* library = ::dlopen(kUmockdevPreload, RTLD_LAZY | RTLD_LOCAL);
  if (library == nullptr) {
    const char* why = ::dlerror();
    throw std::runtime_error(std::string("virtual digitizer: umockdev's preload library cannot be loaded (") +
                             (why != nullptr ? why : kUmockdevPreload) + "): apt-get install umockdev");
  }
  ::dlclose(library);
  const std::string new_preload = preloadWithUmockdev(preload);
  std::vector<std::string> args = ownArguments();
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  if (::setenv("LD_PRELOAD", new_preload.c_str(), 1) != 0 || ::setenv(kReexecMarker, "1", 1) != 0)
    throw std::runtime_error(std::string("virtual digitizer: setenv: ") + std::strerror(errno));
  std::fflush(nullptr);
  ::execv("/proc/self/exe", argv.data());
  throw std::runtime_error(std::string("virtual digitizer: re-executing /proc/self/exe with LD_PRELOAD=") + new_preload +
                           ": " + std::strerror(errno));
}

std::unique_ptr<sim::VirtualDigitizer> hostVirtualDigitizer(const CellConfig& cell, sim::VirtualDigitizerOptions options) {
  if (!cell.digitizer_virtual) return nullptr;
  requireUmockdevPreload();
  if (!cell.digitizer_serial.empty()) options.identity.serial = cell.digitizer_serial;  // the one the cell looks for
  try {
    return std::make_unique<sim::VirtualDigitizer>(options);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("virtual digitizer: ") + e.what());
  }
}

}  // namespace stampscan::station

namespace stampscan::station {

sim::VirtualCellOptions servedDevicesOf(const CellConfig& cell) {
  sim::VirtualCellOptions o;
  o.cmm_address = cell.cmm.host;
  o.cmm_port = static_cast<std::uint16_t>(cell.cmm.port);
  o.plc_address = cell.plc.host;
  o.plc_port = cell.plc.port;
  o.plc_unit_id = static_cast<std::uint8_t>(cell.plc_unit_id);
  o.plc_registers = cell.plc_registers;
  o.cameras = true;
  o.left_address = cell.left_camera.address;
  o.left_serial = cell.left_camera.serial;
  o.right_address = cell.right_camera.address;
  o.right_serial = cell.right_camera.serial;
  return o;
}

HostedVirtualCell::HostedVirtualCell(const sim::ScanParams& world, const acquisition::CellConfig& base,
                                     std::shared_ptr<sim::CellReplay> replay, bool cameras)
    : config_(base) {
  sim::VirtualCellOptions o = servedDevicesOf(base);
  o.world = world;
  o.replay = std::move(replay);
  o.cmm_port = 0;  // free ports: a served cell or another scan may hold the configured ones
  o.plc_port = 0;
  o.cameras = cameras;
  cell_ = std::make_unique<sim::VirtualCell>(o);
  acquisition::CellConfig with_digitizer = base;
  with_digitizer.digitizer_virtual = true;
  digitizer_ = hostVirtualDigitizer(with_digitizer, cell_->digitizerOptions());
  digitizer_->setTimedProfileSource(cell_->profileSource());
  cell_->start();
  config_.cmm.port = cell_->cmm().port();
  config_.plc.port = cell_->plc().port();
  config_.digitizer_virtual = true;
}

jobs::SimulationTruth HostedVirtualCell::truthOfScan(const sim::ScanParams& world, acquisition::ScanPlan& plan) {
  // The truth keeps the part it was made of, whatever part the cell loads next.
  const std::shared_ptr<const sim::FormedPart> part = cell_->sharedPart();
  const Eigen::Isometry3d machine_from_datum = sim::machineFromDatum(world);
  jobs::SimulationTruth truth{sim::groundTruth(*part, world.grid, machine_from_datum), cell_->truth().digitizer_latency_ns};
  truth.thickness_strain_at = [part, datum_from_machine = machine_from_datum.inverse()](const fitting::Vec3& point) {
    const fitting::Vec3 on_part = datum_from_machine * point;
    return part->deformationAt(on_part.x(), on_part.y()).thickness_strain;
  };
  const sim::ElementVisibility visibility = sim::visibleElements(world, plan, truth.elements);
  truth.visible = visibility.visibleOr();
  sim::predictElements(plan, visibility);
  return truth;
}

HostedVirtualCell::~HostedVirtualCell() {
  cell_->stop();
  digitizer_.reset();
}

}  // namespace stampscan::station
