// A virtual GigE Vision camera of the cell: an Aravis fake camera (ArvGvFakeCamera) run in this
// process, serving GVCP on UDP 3956 and GVSP of one loopback address. The station reaches it
// through the same GigECamera driver as the real cameras; only the address/serial differ.
// The virtual cell has "left" on 127.0.0.1 and "right" on 127.0.0.2 (ARCHITECTURE.md).
//
// Network: Aravis picks the fake camera's interface by address (arv_network_get_interface_by_
// address, then by name), so both cameras live on `lo`, each bound to its own address; the second
// address must exist on lo (`ip addr add 127.0.0.2/32 dev lo`, root): ensureLoopbackAddress().
// Only 127.0.0.0/8 addresses are accepted, so a virtual camera never listens on a real network.
//
// Images: the fake camera's fill-pattern hook calls the frame source, which writes width x height
// pixels of the current pixel format; without a source (or when it returns false) a test pattern
// is drawn (testPattern()).
//
// Thread safety: the frame source runs on the fake camera's thread; setFrameSource() and
// setLostPacketRatio() may be called at any time from any thread.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>

namespace stampscan::sim {

struct FrameRequest {
  std::uint32_t width = 0, height = 0;
  std::uint32_t bytes_per_pixel = 1;  // 1 for Mono8, 2 for Mono16 (little endian)
  std::uint64_t index = 0;            // frames filled so far by this camera
};

// Writes the image into `out` (width * height * bytes_per_pixel bytes); false: use the test pattern.
using FrameSource = std::function<bool(const FrameRequest& request, std::span<std::uint8_t> out)>;

struct VirtualCameraOptions {
  std::string address = "127.0.0.1";  // a loopback address, present on lo
  std::string serial = "STAMPSCAN-LEFT";
  std::string genicam_file;           // empty: Aravis' built-in fake camera description
  double lost_packet_ratio = 0.0;     // GVSP packets the fake camera drops, 0..1
  double trigger_poll_hz = 1000.0;    // how often the fake camera looks for a software trigger
};

struct LoopbackStatus {
  bool ok = false;
  std::string reason;  // why not, for GTEST_SKIP and the operator
};

class VirtualCamera {
 public:
  explicit VirtualCamera(VirtualCameraOptions options = {});
  ~VirtualCamera();
  VirtualCamera(const VirtualCamera&) = delete;
  VirtualCamera& operator=(const VirtualCamera&) = delete;

  // Creates the fake camera and starts serving; throws std::runtime_error naming the address.
  void start();
  // Destroys the fake camera (as if unplugged). Idempotent.
  void stop() noexcept;
  bool running() const;

  void setFrameSource(FrameSource source);
  void setLostPacketRatio(double ratio);
  const VirtualCameraOptions& options() const { return options_; }
  std::uint64_t framesFilled() const;

  // The image drawn without a frame source: a diagonal ramp shifted by the frame index.
  static void testPattern(const FrameRequest& request, std::span<std::uint8_t> out);

  // Makes sure `address` (127.x.y.z) is on lo, adding it with `ip addr add ADDRESS/32 dev lo` when
  // it is missing and we are root. Never touches other interfaces.
  static LoopbackStatus ensureLoopbackAddress(const std::string& address);

  struct Impl;

 private:
  VirtualCameraOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::sim
