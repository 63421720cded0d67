// GigECamera's streaming: the GVSP buffer pool and the stream thread.
//
// Buffer flow (as in Aravis' own design): buffer_count buffers are pushed to the ArvStream's input
// queue; Aravis' receive thread fills them from GVSP packets and moves each finished one (complete
// or not) to the output queue; the stream thread pops with pop_timeout, delivers a SUCCESS buffer
// to the callback, counts any other status by reason, and pushes the buffer back. No allocation
// per frame, no unbounded queue: when the consumer is slow Aravis runs out of input buffers and
// counts an underrun.
#include <algorithm>
#include <limits>

#include "gige_camera_impl.hpp"

namespace stampscan::drivers::camera {

namespace {

const char* statusReason(ArvBufferStatus status) {
  switch (status) {
    case ARV_BUFFER_STATUS_SUCCESS: return "success";
    case ARV_BUFFER_STATUS_CLEARED: return "cleared";
    case ARV_BUFFER_STATUS_TIMEOUT: return "timeout";
    case ARV_BUFFER_STATUS_MISSING_PACKETS: return "missing-packets";
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID: return "wrong-packet-id";
    case ARV_BUFFER_STATUS_SIZE_MISMATCH: return "size-mismatch";
    case ARV_BUFFER_STATUS_FILLING: return "filling";
    case ARV_BUFFER_STATUS_ABORTED: return "aborted";
    default: return "unknown";
  }
}

std::int64_t ticksToNs(std::int64_t ticks, std::int64_t frequency) {
  if (frequency <= 0 || frequency == 1'000'000'000) return ticks;
  return static_cast<std::int64_t>(static_cast<long double>(ticks) * 1e9L / static_cast<long double>(frequency));
}

bool has(ArvCamera* cam, const char* feature) {
  return arv_camera_is_feature_available(cam, feature, nullptr) != FALSE;
}

}  // namespace

// The device-to-station clock offset, measured once per stream session.
// - TimestampLatch: when the camera can latch its timestamp counter (GevTimestampControlLatch and
//   GevTimestampValue, or SFNC's TimestampLatch/TimestampLatchValue), the latch command is
//   bracketed by two station clock reads; the offset is the bracket midpoint minus the latched
//   value, and the tightest of 5 brackets is kept (error <= half that bracket, typically < 1 ms).
// - FirstFrames otherwise (the Aravis fake camera has no latch): the minimum, over the first 16
//   frames, of (station time at pop - device timestamp). The minimum removes the queueing delay
//   but not the transfer time, so station times come out late by the fastest frame's transfer.
void GigECamera::Impl::measureClockLocked() {
  ArvCamera* cam = camera.get();
  const char* latch = nullptr;
  const char* value = nullptr;
  if (has(cam, "GevTimestampControlLatch") && has(cam, "GevTimestampValue")) {
    latch = "GevTimestampControlLatch";
    value = "GevTimestampValue";
  } else if (has(cam, "TimestampLatch") && has(cam, "TimestampLatchValue")) {
    latch = "TimestampLatch";
    value = "TimestampLatchValue";
  }
  offset_samples = 0;
  if (latch == nullptr) {
    clock_method = ClockSyncMethod::FirstFrames;
    return;
  }
  std::int64_t frequency = 1'000'000'000;  // SFNC's TimestampLatchValue is in ns
  if (has(cam, "GevTimestampTickFrequency")) {
    frequency = arv_camera_get_integer(cam, "GevTimestampTickFrequency", nullptr);
  }
  std::int64_t best_bracket = std::numeric_limits<std::int64_t>::max();
  for (int i = 0; i < 5; ++i) {
    glue::Error e;
    const std::int64_t before = stationNow();
    arv_camera_execute_command(cam, latch, e.out());
    const std::int64_t ticks = arv_camera_get_integer(cam, value, e.out());
    const std::int64_t after = stationNow();
    if (e) break;
    if (after - before < best_bracket) {
      best_bracket = after - before;
      clock_offset_ns = before + (after - before) / 2 - ticksToNs(ticks, frequency);
    }
  }
  clock_method = best_bracket == std::numeric_limits<std::int64_t>::max() ? ClockSyncMethod::FirstFrames
                                                                         : ClockSyncMethod::TimestampLatch;
}

void GigECamera::Impl::startSessionLocked() {
  ArvCamera* cam = camera.get();
  glue::Error e;
  const char* format = arv_camera_get_pixel_format_as_string(cam, nullptr);
  session_pixel_format = format != nullptr ? format : "";
  const char* mode = arv_camera_get_string(cam, "TriggerMode", nullptr);
  session_trigger = mode != nullptr && std::string(mode) == "On" ? TriggerMode::Software : TriggerMode::FreeRun;
  const guint payload = arv_camera_get_payload(cam, e.out());
  if (e || payload == 0) throw owner.fault("stream", "cannot read PayloadSize: " + e.message());
  stream.reset(arv_camera_create_stream(cam, nullptr, nullptr, e.out()));
  if (!stream || e) throw owner.fault("stream", "cannot open the GVSP stream: " + e.message());
  glue::setPacketResend(stream.get(), owner.options_.packet_resend);
  // Room for several frames in the socket: a receive thread that a loaded machine holds back for a
  // moment must find the burst still there.
  glue::setSocketBuffer(stream.get(), static_cast<int>(std::clamp<std::uint64_t>(4ULL * payload, 8ULL << 20, 1ULL << 30)));
  for (std::size_t i = 0; i < owner.options_.buffer_count; ++i) {
    arv_stream_push_buffer(stream.get(), arv_buffer_new(payload, nullptr));
  }
  arv_camera_set_acquisition_mode(cam, ARV_ACQUISITION_MODE_CONTINUOUS, nullptr);
  session_trigger_base = triggers_issued;
  first_frame_id.reset();
  last_raw_id.reset();
  wrap_offset = 0;
  realtime_to_station_ns = stationNow() - g_get_real_time() * 1000;
  measureClockLocked();
  arv_camera_start_acquisition(cam, e.out());
  if (e) {
    stream.reset();
    throw owner.fault("stream", "AcquisitionStart failed: " + e.message());
  }
}

void GigECamera::Impl::endSessionLocked(bool device_alive) noexcept {
  // Stopping a camera that is gone would only wait for GVCP timeouts.
  if (device_alive && camera) arv_camera_stop_acquisition(camera.get(), nullptr);
  stream.reset();  // joins Aravis' receive thread and frees the buffers
}

// GVSP 1.x block ids are 16 bits and skip 0 (65535 is followed by 1); GVSP 2.x extended ids are
// 64 bits and do not wrap. Unwrapped ids increase within a stream session.
std::uint64_t GigECamera::Impl::unwrapFrameId(std::uint64_t raw) {
  if (last_raw_id && raw < *last_raw_id && *last_raw_id <= 0xFFFF && *last_raw_id - raw > 0x8000) {
    wrap_offset += 0xFFFF;
  }
  last_raw_id = raw;
  return raw + wrap_offset;
}

void GigECamera::Impl::handleBuffer(ArvBuffer* buffer, std::int64_t received_ns) {
  const ArvBufferStatus status = arv_buffer_get_status(buffer);
  const std::uint64_t id = unwrapFrameId(arv_buffer_get_frame_id(buffer));
  // GVSP block ids start at 1 and skip 0: a buffer with id 0 holds stray packets (Aravis's packet
  // socket can catch another camera's on the same host as a stream opens) and must not become
  // the first frame, or every trigger id of the session would be off by one.
  if (!first_frame_id && id != 0) first_frame_id = id;
  {
    std::lock_guard lock(stats_mutex);
    guint64 completed = 0, failures = 0, underruns = 0;
    arv_stream_get_statistics(stream.get(), &completed, &failures, &underruns);
    stats.aravis_failures = failures;
    stats.aravis_underruns = underruns;
    if (status != ARV_BUFFER_STATUS_SUCCESS) {
      ++stats.incomplete;
      ++stats.incomplete_by_reason[statusReason(status)];
      return;  // never delivered as a good frame
    }
    if (!first_frame_id) {  // block id 0: stray packets, whatever Aravis made of them
      ++stats.incomplete;
      ++stats.incomplete_by_reason["stray-block-0"];
      return;
    }
  }
  size_t size = 0;
  const void* data = arv_buffer_get_image_data(buffer, &size);
  if (data == nullptr) {
    std::lock_guard lock(stats_mutex);
    ++stats.incomplete;
    ++stats.incomplete_by_reason["not-an-image"];
    return;
  }
  FrameView view;
  view.frame_id = id;
  // In software trigger mode every trigger makes exactly one frame, so block ids count triggers.
  view.trigger_id = session_trigger == TriggerMode::Software ? session_trigger_base + 1 + (id - *first_frame_id) : 0;
  view.device_time_ns = static_cast<std::int64_t>(arv_buffer_get_timestamp(buffer));
  if (clock_method == ClockSyncMethod::FirstFrames && offset_samples < 16) {
    // Aravis stamps the buffer with the host's real-time clock when the frame's first packet
    // arrived: free of the queueing before our pop. Without it, the pop time is used.
    const auto arrival = static_cast<std::int64_t>(arv_buffer_get_system_timestamp(buffer));
    const std::int64_t seen = arrival > 0 ? arrival + realtime_to_station_ns : received_ns;
    const std::int64_t candidate = seen - view.device_time_ns;
    if (offset_samples == 0 || candidate < clock_offset_ns) clock_offset_ns = candidate;
    ++offset_samples;
  }
  view.station_time_ns = view.device_time_ns + clock_offset_ns;
  view.width = static_cast<std::uint32_t>(arv_buffer_get_image_width(buffer));
  view.height = static_cast<std::uint32_t>(arv_buffer_get_image_height(buffer));
  view.pixel_format_code = arv_buffer_get_image_pixel_format(buffer);
  view.pixel_format = session_pixel_format;
  view.bytes = std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(data), size);
  try {
    if (callback) callback(view);
  } catch (const std::exception& ex) {
    owner.fault("callback", std::string("frame callback threw: ") + ex.what());
  }
  std::lock_guard lock(stats_mutex);
  ++stats.delivered;
}

bool GigECamera::Impl::reconnectFromThread() {
  while (!stop_requested) {
    try {
      std::lock_guard lock(camera_mutex);
      quiet = true;
      openLocked();
      quiet = false;
      startSessionLocked();
      {
        std::lock_guard stats_lock(stats_mutex);
        ++stats.reconnects;
      }
      owner.setState(DeviceState::Busy);
      return true;
    } catch (const DeviceError&) {
      quiet = false;
    }
    std::unique_lock lock(wake_mutex);
    wake.wait_for(lock, owner.options_.reconnect_period, [this] { return stop_requested.load(); });
  }
  return false;
}

void GigECamera::Impl::run() {
  const auto pop_us = static_cast<guint64>(
      std::chrono::duration_cast<std::chrono::microseconds>(owner.options_.pop_timeout).count());
  const std::int64_t silence_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(owner.options_.silence_limit).count();
  std::int64_t last_activity = stationNow();
  while (!stop_requested) {
    ArvBuffer* buffer = arv_stream_timeout_pop_buffer(stream.get(), pop_us);
    const std::int64_t now = stationNow();
    if (buffer != nullptr) {
      last_activity = now;
      handleBuffer(buffer, now);
      arv_stream_push_buffer(stream.get(), buffer);
      continue;
    }
    {
      std::lock_guard lock(stats_mutex);
      ++stats.pop_timeouts;
    }
    // A frame is due in free-run always, in trigger mode only after a trigger not yet answered.
    const std::int64_t since =
        session_trigger == TriggerMode::FreeRun ? last_activity : std::max<std::int64_t>(last_trigger_ns, 0);
    const bool due = session_trigger == TriggerMode::FreeRun || since > last_activity;
    const bool silent = due && now - since > silence_ns;
    if (!control_lost && !silent) continue;
    if (!control_lost) {
      {
        std::lock_guard lock(stats_mutex);
        ++stats.silences;
      }
      owner.fault("timeout", "no frame for " + std::to_string((now - since) / 1'000'000) + " ms");
      if (probeDevice()) {  // alive, just quiet (e.g. a lost trigger): keep streaming
        last_activity = stationNow();
        owner.setState(DeviceState::Busy);
        continue;
      }
    }
    owner.fault("disconnected", control_lost ? "GVCP control lost (heartbeat unanswered)"
                                             : "the camera stopped sending and does not answer GVCP");
    {
      std::lock_guard lock(stats_mutex);
      ++stats.disconnects;
    }
    {
      std::lock_guard lock(camera_mutex);
      endSessionLocked(false);
      closeLocked(true);
    }
    if (!owner.options_.auto_reconnect || !reconnectFromThread()) return;
    last_activity = stationNow();
  }
}

void GigECamera::startStreaming(FrameCallback on_frame) {
  std::lock_guard lock(impl_->lifecycle_mutex);
  if (impl_->streaming) throw fault("busy", "startStreaming() while already streaming");
  {
    std::lock_guard camera_lock(impl_->camera_mutex);
    if (!impl_->camera) throw fault("disconnected", "startStreaming() while the camera is not open");
    impl_->startSessionLocked();
  }
  impl_->callback = std::move(on_frame);
  impl_->stop_requested = false;
  impl_->streaming = true;
  impl_->thread = std::thread([impl = impl_.get()] { impl->run(); });
  setState(DeviceState::Busy);
}

void GigECamera::stopStreaming() noexcept {
  std::lock_guard lock(impl_->lifecycle_mutex);
  if (!impl_->streaming) return;
  {
    std::lock_guard wake_lock(impl_->wake_mutex);
    impl_->stop_requested = true;
  }
  impl_->wake.notify_all();
  if (impl_->thread.joinable()) impl_->thread.join();
  {
    std::lock_guard camera_lock(impl_->camera_mutex);
    impl_->endSessionLocked(impl_->camera && !impl_->control_lost);
  }
  impl_->streaming = false;
  impl_->callback = nullptr;
  if (state() == DeviceState::Busy) setState(DeviceState::Ready);
}

bool GigECamera::streaming() const {
  std::lock_guard lock(impl_->lifecycle_mutex);
  return impl_->streaming;
}

}  // namespace stampscan::drivers::camera
