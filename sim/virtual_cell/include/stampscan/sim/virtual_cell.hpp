// The virtual cell as one simulated world. The part sits on its fixture, the reference sphere and
// the calibration plate stand on the table beside it; the virtual CMM moves the head among them and
// the virtual PLC holds the door, the clamp and the laser shutter. The virtual digitizer's profiles
// are rendered from the head pose the CMM has at the instant of each exposure, through the true
// (not the nominal) mount of the digitizer on the head; with the shutter closed it sees nothing.
// The virtual cameras (when asked for) render the world from the head pose at each frame, through
// their true intrinsics and mounts. The truth is sim::drawCellTruth of the world's seed: the same
// cell as a simulated session of that seed.
//
// The station reaches these devices only through its drivers on their wire protocols (I++ DME on
// TCP, Modbus TCP, USB under umockdev), exactly as it reaches a real cell. The virtual digitizer is
// made by the process that hosts it (it must exist before any libusb context); this class gives it
// its options and its profile source.
//
// Rendering a full-resolution frame casts millions of rays; done at the trigger, the head would
// wait for it at every view, on a machine that is also measuring. Since a camera frame is taken with
// the head standing still, the cell renders the light the cameras will see at the CMM's
// destination while the head travels there (and while the laser's shutter is closed: a sweeping
// digitizer renders its own profiles in real time). At the trigger, with the head standing at that
// very pose, only the sensor's exposure (noise, quantisation) is left to do; anywhere else the frame
// is rendered whole, as before. The frames are the same either way, and still reach the station
// over GigE Vision through its driver.
//
// Thread safety: start() and stop() from one thread; the profile source runs on the virtual
// digitizer's thread and only reads the CMM's and the PLC's state (both thread-safe).
#pragma once

#include "stampscan/sim/cell_replay.hpp"
#include "stampscan/sim/scan_scenario.hpp"
#include "stampscan/sim/virtual_camera.hpp"
#include "stampscan/sim/virtual_cmm.hpp"
#include "stampscan/sim/virtual_digitizer.hpp"
#include "stampscan/sim/virtual_plc.hpp"

#include <Eigen/Geometry>

#include <array>
#include <atomic>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace stampscan::sim {

struct VirtualCellOptions {
  // The world: part, grid, reference sphere, calibration plate, the digitizer's optics, the seed of
  // the sensors' noise and of the mount's deviation from its drawing.
  ScanParams world;
  std::string cmm_address = "127.0.0.1";
  std::uint16_t cmm_port = 1294;  // 0: any free port (read it from cmm().port())
  std::string plc_address = "127.0.0.1";
  int plc_port = 1502;            // 0: any free port
  // The PLC as the cell file describes it ([plc] unit_id, [plc.registers]): the unit id it answers
  // and where it serves each signal.
  std::uint8_t plc_unit_id = 1;
  drivers::plc::RegisterMap plc_registers;
  // The stereo pair: Aravis fake GigE Vision cameras (GVCP on UDP 3956 of each address, so one
  // cell per machine at a time), rendering the world at the world's image scale.
  bool cameras = false;
  std::string left_address = "127.0.0.1", left_serial = "STAMPSCAN-LEFT";
  std::string right_address = "127.0.0.2", right_serial = "STAMPSCAN-RIGHT";

  // Which servers start() starts. `station sim serve` runs each device in a process of its own, so
  // that a fault in one cannot take the others down; each process builds the same world.
  bool serve_cmm = true, serve_plc = true;
  // Where the cameras read the head's pose when the CMM is served by another process (empty: from
  // this object's CMM). Position in mm, head_a/head_b in radians, as VirtualCmmStatus has them.
  std::function<VirtualCmmStatus()> head_status;

  // Replay (cell_replay.hpp): when set, the CMM follows the recorded head track and the digitizer and
  // the cameras serve the recorded profiles and frames instead of rendering the world.
  std::shared_ptr<CellReplay> replay;
};

class VirtualCell {
 public:
  explicit VirtualCell(VirtualCellOptions options = {});
  ~VirtualCell();
  VirtualCell(const VirtualCell&) = delete;
  VirtualCell& operator=(const VirtualCell&) = delete;

  // Starts the CMM's and the PLC's servers (and the cameras); throws std::runtime_error naming the
  // address.
  void start();
  void stop() noexcept;

  // Fault injection: the right camera goes away (as if unplugged).
  void stopRightCamera() {
    if (cameras_.size() > 1) cameras_[1]->stop();
  }

  VirtualCmm& cmm() { return *cmm_; }
  VirtualPlc& plc() { return *plc_; }

  // For the process that hosts the virtual digitizer: paced at its rate, its fan as the world's
  // digitizer has it, stamped with the world's latency; and the world's profiles.
  VirtualDigitizerOptions digitizerOptions() const;
  VirtualDigitizer::TimedProfileSource profileSource();

  const VirtualCellOptions& options() const { return options_; }
  // What the station must find out by calibrating: tests compare with it.
  const CellTruth& truth() const { return truth_; }
  // The part on the fixture (as loaded last); shared: alive as long as the pointer, whatever is loaded next.
  const FormedPart& part() const;
  std::shared_ptr<const FormedPart> sharedPart() const;
  // Puts another part on the fixture, as an operator loads the next part: the digitizer and the
  // cameras see it from now on. Between scans. The part stays alive as long as the returned pointer.
  // `part_world` gives the part (its family, parameters and grid); the cell stays as it is.
  std::shared_ptr<const FormedPart> loadPart(const ScanParams& part_world);

 private:
  class WorldScene;
  // The head pose a frame is rendered from: the CMM's six numbers, compared exactly (a machine at
  // rest stands exactly at its commanded target).
  struct HeadKey {
    std::array<double, 3> position{};
    double a = 0, b = 0;
    bool operator==(const HeadKey&) const = default;
  };
  bool renderFrame(int camera, const FrameRequest& request, std::span<std::uint8_t> out) const;
  std::vector<float> radianceAt(int camera, const HeadKey& head, const std::function<bool()>& cancelled = {}) const;
  bool laserSweeping() const;
  void renderAhead();  // the render-ahead thread

  // The seed of a camera's sensor noise in its `index`-th frame: the same image whoever exposes it.
  std::uint64_t exposureSeed(int camera, std::uint64_t index) const;

  // The light both cameras see from one head pose, rendered ahead, and each camera's next frame
  // exposed from it (guarded by ahead_mutex_): at the trigger the frame is only copied out, as a
  // real camera's image is ready as soon as its exposure ends.
  struct Ahead {
    HeadKey head;
    std::array<std::vector<float>, 2> radiance;
    struct Exposed {
      std::vector<std::uint8_t> bytes;
      std::uint64_t index = 0;  // the camera's frame it is
      int bits = 0;
    };
    std::array<Exposed, 2> exposed;
    bool ready = false, rendering = false;
  };
  // The bit depth each camera was last asked for (the ahead exposure's guess for its next frame).
  mutable std::array<std::atomic<int>, 2> frame_bits_{};
  mutable std::mutex ahead_mutex_;
  mutable std::condition_variable ahead_changed_;
  Ahead ahead_;
  // Frames waiting for the pose under way (guarded by ahead_mutex_): it is finished even when the
  // head has moved on, which it may as soon as the exposure ended.
  mutable int ahead_awaited_ = 0;
  // A frame was taken since the laser last swept: the head is among views, and its next stop is
  // likely another (the render-ahead leaves the sweeps' starts and the park alone otherwise).
  mutable std::atomic<bool> among_views_{false};
  bool ahead_stop_ = true;
  std::thread ahead_thread_;
  bool replayFrame(int camera, const FrameRequest& request, std::span<std::uint8_t> out) const;

  VirtualCellOptions options_;
  CellTruth truth_;
  // The world the sensors see; replaced whole when a part is loaded (read by the digitizer's and the
  // cameras' threads).
  std::atomic<std::shared_ptr<const WorldScene>> scene_;
  std::unique_ptr<VirtualCmm> cmm_;
  std::unique_ptr<VirtualPlc> plc_;
  std::vector<std::unique_ptr<VirtualCamera>> cameras_;
  std::unique_ptr<CameraRenderer> renderers_[2];
};

}  // namespace stampscan::sim
