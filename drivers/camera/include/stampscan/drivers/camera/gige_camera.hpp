// One GigE Vision camera of the stereo pair, through Aravis: GVCP for control (GenICam features),
// GVSP for the images. The same driver talks to the real cameras and to the virtual cameras of
// sim/virtual_camera (Aravis fake cameras on loopback); only the serial or address differs.
// README.md in this folder explains the mapping to GigE Vision, the buffer flow and the clocks.
//
// Thread safety: every public method may be called from any thread. One mutex guards the Aravis
// camera (GVCP requests are serialised anyway); the stream thread owns the Aravis stream. The frame
// callback runs on the stream thread: it must not call stopStreaming() or reconnect() (deadlock).
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "stampscan/drivers/device.hpp"

namespace stampscan::drivers::camera {

enum class TriggerMode { FreeRun, Software };

// Region of interest in sensor pixels; width/height 0 means "the whole sensor".
struct Roi {
  std::int64_t x = 0, y = 0, width = 0, height = 0;
  bool operator==(const Roi&) const = default;
};

// What configure() writes to the camera; unset optionals leave the device's own value.
struct CameraConfig {
  std::string pixel_format = "Mono8";       // a GenICam PixelFormat entry the device offers
  std::optional<double> exposure_us;        // ExposureTime (or ExposureTimeAbs)
  std::optional<double> gain;               // Gain (or GainRaw)
  Roi roi;                                  // Width, Height, OffsetX, OffsetY
  std::optional<std::uint32_t> packet_size; // GevSCPSPacketSize, bytes per GVSP packet
  std::optional<double> frame_rate_hz;      // AcquisitionFrameRate, free-run only
  TriggerMode trigger = TriggerMode::FreeRun;  // Software: TriggerMode=On, TriggerSource=Software
};

struct GigECameraOptions {
  // How to find the camera: by serial (preferred; survives an IP change) or by IPv4 address.
  std::string serial;
  std::string address;
  std::size_t buffer_count = 8;                 // buffers pushed to the GVSP stream
  std::chrono::milliseconds pop_timeout{100};   // the stream thread's wait for one buffer
  // No buffer for this long while one is due (free-run, or a trigger outstanding) is reported as
  // fault "timeout" and the device is probed; a failed probe means "disconnected".
  std::chrono::milliseconds silence_limit{1000};
  bool auto_reconnect = true;                   // the stream thread re-opens by serial
  // GVSP packet resend requests. A real camera honours them; the fake camera ignores them.
  bool packet_resend = true;
  std::chrono::milliseconds reconnect_period{200};
  // The station clock, ns. Default: std::chrono::system_clock since the Unix epoch.
  std::function<std::int64_t()> station_clock;
};

// One complete frame, as delivered to the callback. The bytes are the Aravis buffer's: valid only
// during the callback (the buffer goes back to the stream right after it); copy what you keep.
struct FrameView {
  std::uint64_t frame_id = 0;        // GVSP block id, unwrapped to be monotonic (16-bit ids wrap)
  std::uint64_t trigger_id = 0;      // software trigger sequence number (0 in free-run)
  std::int64_t device_time_ns = 0;   // camera clock
  std::int64_t station_time_ns = 0;  // device_time_ns + clock offset (station clock)
  std::uint32_t width = 0, height = 0;
  std::string pixel_format;          // "Mono8", "Mono16", ...
  std::uint32_t pixel_format_code = 0;  // the PFNC code on the wire
  std::span<const std::uint8_t> bytes;
};

// A frame that owns its bytes (StereoPair, tests).
struct Frame {
  FrameView info;  // info.bytes points into data
  std::vector<std::uint8_t> data;
  static Frame copyOf(const FrameView& view);
  Frame() = default;
  Frame(const Frame& other);
  Frame& operator=(const Frame& other);
  Frame(Frame&&) noexcept = default;
  Frame& operator=(Frame&&) noexcept = default;
};

struct StreamStats {
  std::uint64_t delivered = 0;
  std::uint64_t incomplete = 0;  // buffers not SUCCESS: never delivered
  std::map<std::string, std::uint64_t> incomplete_by_reason;  // "missing-packets", "timeout", ...
  std::uint64_t pop_timeouts = 0;   // pops that waited pop_timeout with no buffer
  std::uint64_t silences = 0;       // "timeout" faults: a due frame did not come in silence_limit
  std::uint64_t disconnects = 0;
  std::uint64_t reconnects = 0;
  std::uint64_t aravis_failures = 0, aravis_underruns = 0;  // arv_stream_get_statistics
};

// How the device-to-station clock offset was measured (see README.md "Clocks").
enum class ClockSyncMethod { None, TimestampLatch, FirstFrames };

class GigECamera : public Device {
 public:
  using FrameCallback = std::function<void(const FrameView&)>;

  explicit GigECamera(std::string name, GigECameraOptions options);
  ~GigECamera() override;

  // Writes the configuration (stored: reconnect() writes it again). Not while streaming.
  // Throws DeviceError "config" naming the feature when the device refuses a value.
  void configure(const CameraConfig& config);
  // Reads the current values back from the device.
  CameraConfig readConfig();
  // The PixelFormat entries the device offers.
  std::vector<std::string> pixelFormats();
  // Sensor size (SensorWidth, SensorHeight).
  std::pair<std::int64_t, std::int64_t> sensorSize();

  // Starts acquisition with buffer_count buffers; complete frames go to on_frame (stream thread).
  void startStreaming(FrameCallback on_frame);
  void stopStreaming() noexcept;
  bool streaming() const;
  // TriggerSoftware; returns the trigger id the resulting frame will carry (1, 2, ...).
  std::uint64_t softwareTrigger();

  // Re-opens the camera by serial (the one identified at connect), writes the stored configuration
  // again and restarts streaming if it was on. Also done by the stream thread on its own when
  // auto_reconnect is set. Throws DeviceError "disconnected" when the camera is not found.
  void reconnect();

  StreamStats stats() const;
  std::int64_t clockOffsetNs() const;  // station clock minus camera clock
  ClockSyncMethod clockSyncMethod() const;
  const GigECameraOptions& options() const { return options_; }

  struct Impl;  // public for the stream thread's helpers in src/, opaque to users

 protected:
  void connectDevice() override;
  void disconnectDevice() noexcept override;
  DeviceIdentity identifyDevice() override;
  void checkDevice() override;

 private:
  friend struct Impl;
  GigECameraOptions options_;
  std::unique_ptr<Impl> impl_;
};

const char* toString(ClockSyncMethod method);

}  // namespace stampscan::drivers::camera
