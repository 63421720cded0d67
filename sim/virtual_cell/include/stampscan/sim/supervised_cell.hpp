// The virtual cell served to other programs, one process per device: the CMM, the PLC and the two
// cameras each run in a process of their own, forked from the supervisor, so that a fault in one
// (a hostile datagram that crashes a camera, say) cannot take the others down; the supervisor starts
// again a device that stops. Every process builds the same world from the same options (and seed);
// the cameras render from the head pose that the CMM's process publishes in a shared page (a
// replay's time map travels there too). `station sim serve` is a thin caller.
//
// Thread safety: construct it before the process starts any thread (a fork copies only the calling
// thread); use it from one thread.
#pragma once

#include "stampscan/sim/virtual_cell.hpp"

#include <sys/types.h>

#include <functional>
#include <string>
#include <vector>

namespace stampscan::sim {

struct SharedHead;

class SupervisedVirtualCell {
 public:
  // Forks the devices' processes and waits (20 s each, 120 s for a replay, which reads its
  // recording first) until each serves. Throws naming the device and its own error.
  SupervisedVirtualCell(VirtualCellOptions options, std::string replay_trace = {});
  ~SupervisedVirtualCell();  // stops every device (SIGTERM, SIGKILL after 5 s)
  SupervisedVirtualCell(const SupervisedVirtualCell&) = delete;
  SupervisedVirtualCell& operator=(const SupervisedVirtualCell&) = delete;

  int cmmPort() const { return cmm_port_; }
  int plcPort() const { return plc_port_; }
  // Starts again every device whose process has ended, telling `log` one line per event ("cmm
  // stopped unexpectedly (killed by signal 11 ...); ...", "cmm serving again").
  void restartStopped(const std::function<void(const std::string& line)>& log);

  enum class Device { Cmm, Plc, Cameras };
  struct DeviceProcess {
    Device device;
    pid_t pid = -1;
    int port = 0;
  };

 private:
  VirtualCellOptions options_;
  std::string replay_trace_;
  SharedHead* head_ = nullptr;  // in a MAP_SHARED page
  std::vector<DeviceProcess> devices_;
  int cmm_port_ = 0, plc_port_ = 0;
};

}  // namespace stampscan::sim
