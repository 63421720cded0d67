// A virtual GigE Vision camera of the cell, run in this process: Aravis' camera model
// (ArvFakeCamera: registers, GenICam XML, frame timing, trigger, image filling) behind our own
// GVCP/GVSP server on one loopback address. The station reaches it through the same GigECamera
// driver as the real cameras; only the address/serial differ. The virtual cell has "left" on
// 127.0.0.1 and "right" on 127.0.0.2 (ARCHITECTURE.md).
//
// Network: GVCP is served on ADDRESS:3956 only, plus broadcast discovery on a socket bound to lo
// (so arv_update_device_list() finds the camera, but no other interface reaches it); GVSP goes from
// ADDRESS to the controller's stream channel, only when that is a loopback address. Every request
// is validated before the camera model sees it and bad ones get the GigE Vision error status;
// control (CCP) and its heartbeat behave as on a real camera. Both cameras live on `lo`; the second
// address must exist on lo (`ip addr add 127.0.0.2/32 dev lo`, root): ensureLoopbackAddress().
// Only 127.0.0.0/8 addresses are accepted, so a virtual camera never listens on a real network.
//
// Images: the camera model's fill-pattern hook calls the frame source, which writes width x height
// pixels of the current pixel format; without a source (or when it returns false) a test pattern
// is drawn (testPattern()).
//
// Thread safety: the frame source runs on the camera's stream thread; setFrameSource() and
// setLostPacketRatio() may be called at any time from any thread.
#pragma once

#include <chrono>
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
  // When the exposure started: the software trigger's arrival, or the free-running frame's time.
  // The image shows the world at that instant, however late it is made.
  std::chrono::steady_clock::time_point exposure;
};

// Writes the image into `out` (width * height * bytes_per_pixel bytes); false: use the test pattern.
using FrameSource = std::function<bool(const FrameRequest& request, std::span<std::uint8_t> out)>;

struct VirtualCameraOptions {
  std::string address = "127.0.0.1";  // a loopback address, present on lo
  std::string serial = "STAMPSCAN-LEFT";
  std::string genicam_file;           // empty: Aravis' built-in fake camera description
  double lost_packet_ratio = 0.0;     // GVSP packets the camera drops, 0..1
  double trigger_poll_hz = 1000.0;    // how often the camera looks for a software trigger (a trigger
                                      // write also wakes it at once)
  // GigE Vision's timestamp latch (GevTimestampControlLatch, GevTimestampValue), which most
  // machine-vision cameras offer: a controller reads the camera's clock to the millisecond. Without
  // it (as Aravis' own fake camera) a controller can only estimate the clock from frame arrivals.
  bool timestamp_latch = true;
  // The sensor's size in pixels (SensorWidth, SensorHeight; the image's Width and Height start
  // there). 0: Aravis' model's own, 2048 x 2048. A camera drawn larger than that needs its size here:
  // the model refuses a region wider or taller than its sensor.
  int sensor_width = 0, sensor_height = 0;
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

  // Creates the camera model and starts serving; throws std::runtime_error naming the address
  // (not loopback, not on lo, or UDP 3956 on it taken by another camera or process).
  void start();
  // Stops serving and destroys the camera model (as if unplugged). Idempotent.
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
