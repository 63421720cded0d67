// GigECamera's private state, shared by gige_camera.cpp (control: open, configure, identify) and
// gige_stream.cpp (the GVSP buffer pool and the stream thread).
#pragma once

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <thread>

#include "aravis_glue.hpp"
#include "stampscan/drivers/camera/gige_camera.hpp"

namespace stampscan::drivers::camera {

struct GigECamera::Impl {
  explicit Impl(GigECamera& o) : owner(o) {}
  GigECamera& owner;

  // --- control (camera_mutex) ---
  mutable std::mutex camera_mutex;
  glue::GPtr<ArvCamera> camera;
  unsigned long lost_handler = 0;
  std::atomic<bool> control_lost{false};
  std::string serial, address;  // of the camera last opened: reconnect() looks for this serial
  std::optional<CameraConfig> config;  // what configure() wrote, written again on reconnect
  bool quiet = false;  // the stream thread's reconnect attempts: failures are not logged as faults
  DeviceError fail(const std::string& code, const std::string& text);

  // Opens by serial (or address), hooks control-lost and writes the stored config. Throws
  // DeviceError. Caller holds camera_mutex.
  void openLocked();
  // Drops the camera. `device_lost`: it may have lost contact (silence, control lost), so it is
  // retired (glue::retireLostCamera) rather than dropped on the spot.
  void closeLocked(bool device_lost = false) noexcept;
  // Empty when this process holds the camera's control channel privilege (CCP); otherwise what to
  // tell the operator ("camera S at A is controlled by another application (CCP held)"). With
  // `confirm_by_write`, control is also proven by writing the heartbeat timeout back (as Pylon's
  // heartbeat does), which a camera refuses once another application has taken control over.
  // Caller holds camera_mutex.
  std::string controlProblemLocked(ArvCamera* cam, const std::string& serial_text, const std::string& where,
                                   bool confirm_by_write);
  void applyConfigLocked(const CameraConfig& c);
  int64_t stationNow() const;

  // --- streaming (lifecycle under lifecycle_mutex; the stream itself belongs to the thread) ---
  std::mutex lifecycle_mutex;
  std::thread thread;
  std::atomic<bool> stop_requested{false};
  std::mutex wake_mutex;
  std::condition_variable wake;  // interrupts the reconnect back-off on stop
  FrameCallback callback;
  bool streaming = false;
  glue::GPtr<ArvStream> stream;  // created by startSessionLocked, used by the stream thread only

  // Per stream session (a reconnect starts a new one).
  TriggerMode session_trigger = TriggerMode::FreeRun;
  std::string session_pixel_format;
  std::uint64_t session_trigger_base = 0;   // triggers issued before the session started
  std::optional<std::uint64_t> first_frame_id;
  std::optional<std::uint64_t> last_raw_id;
  std::uint64_t wrap_offset = 0;
  int offset_samples = 0;
  std::int64_t realtime_to_station_ns = 0;  // station clock minus host real-time clock

  std::atomic<std::uint64_t> triggers_issued{0};
  std::atomic<std::int64_t> last_trigger_ns{0};
  std::atomic<std::int64_t> clock_offset_ns{0};
  std::atomic<ClockSyncMethod> clock_method{ClockSyncMethod::None};

  mutable std::mutex stats_mutex;
  StreamStats stats;

  // Creates the stream, pushes the buffers, measures the clock and starts acquisition. Caller
  // holds camera_mutex.
  void startSessionLocked();
  // Stops acquisition (best effort) and drops the stream. Caller holds camera_mutex.
  void endSessionLocked(bool device_alive) noexcept;
  void run();  // the stream thread
  void handleBuffer(ArvBuffer* buffer, std::int64_t received_ns);
  bool probeDevice();  // one GVCP register read; false when the camera does not answer
  bool reconnectFromThread();
  std::uint64_t unwrapFrameId(std::uint64_t raw);
  void measureClockLocked();
};

}  // namespace stampscan::drivers::camera
