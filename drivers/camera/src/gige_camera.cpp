// GigECamera: opening (discovery), identity, GenICam configuration, reconnect. The stream thread
// is in gige_stream.cpp.
#include <cmath>

#include "gige_camera_impl.hpp"

namespace stampscan::drivers::camera {

namespace {

std::string str(const char* s) { return s != nullptr ? std::string(s) : std::string(); }

}  // namespace

const char* toString(ClockSyncMethod method) {
  switch (method) {
    case ClockSyncMethod::None: return "none";
    case ClockSyncMethod::TimestampLatch: return "timestamp-latch";
    case ClockSyncMethod::FirstFrames: return "first-frames";
  }
  return "unknown";
}

Frame Frame::copyOf(const FrameView& view) {
  Frame f;
  f.info = view;
  f.data.assign(view.bytes.begin(), view.bytes.end());
  f.info.bytes = f.data;
  return f;
}

Frame::Frame(const Frame& other) : info(other.info), data(other.data) { info.bytes = data; }

Frame& Frame::operator=(const Frame& other) {
  if (this != &other) {
    info = other.info;
    data = other.data;
    info.bytes = data;
  }
  return *this;
}

GigECamera::GigECamera(std::string name, GigECameraOptions options)
    : Device(std::move(name)), options_(std::move(options)), impl_(std::make_unique<Impl>(*this)) {
  if (!options_.station_clock) {
    options_.station_clock = [] {
      return std::chrono::duration_cast<std::chrono::nanoseconds>(
                 std::chrono::system_clock::now().time_since_epoch())
          .count();
    };
  }
  if (options_.buffer_count < 2) options_.buffer_count = 2;  // one filling, one being read
}

GigECamera::~GigECamera() { disconnect(); }

std::int64_t GigECamera::Impl::stationNow() const { return owner.options_.station_clock(); }

namespace {
void onControlLost(ArvDevice*, void* user) {
  // Aravis' heartbeat thread: only raise the flag; the stream thread (or the next call) acts.
  static_cast<GigECamera::Impl*>(user)->control_lost = true;
}
}  // namespace

DeviceError GigECamera::Impl::fail(const std::string& code, const std::string& text) {
  return quiet ? DeviceError(owner.name(), code, text) : owner.fault(code, text);
}

void GigECamera::Impl::openLocked() {
  const GigECameraOptions& o = owner.options_;
  // Prefer the serial: it survives an address change (DHCP, LLA) and is what reconnect uses.
  const std::string want_serial = !serial.empty() ? serial : o.serial;
  glue::Error error;
  glue::GPtr<ArvCamera> cam;
  std::string id, found_address;
  // With both known, ask the address directly first (a unicast GVCP request, no broadcast
  // discovery wait) and accept it only when the serial matches; else fall back to discovery.
  if (!o.address.empty()) {
    cam.reset(arv_camera_new(o.address.c_str(), error.out()));
    error.clear();
    if (cam && !want_serial.empty() && str(arv_camera_get_device_serial_number(cam.get(), nullptr)) != want_serial) {
      cam.reset();
    }
    if (cam) id = found_address = o.address;
  }
  if (!cam && !want_serial.empty()) {
    id = glue::findDeviceIdBySerial(want_serial, &found_address);
    if (id.empty()) {
      throw fail("disconnected", "no GigE Vision camera with serial '" + want_serial + "' answers discovery" +
                                     (o.address.empty() ? std::string() : " nor at " + o.address));
    }
    cam.reset(arv_camera_new(id.c_str(), error.out()));
    if (!cam || error) throw fail("disconnected", "cannot open camera '" + id + "': " + error.message());
  }
  if (!cam) {
    throw fail("disconnected", o.address.empty() ? std::string("no serial nor address configured")
                                                 : "no GigE Vision camera answers at " + o.address);
  }
  const std::string got_serial = str(arv_camera_get_device_serial_number(cam.get(), nullptr));
  if (!want_serial.empty() && got_serial != want_serial) {
    throw fail("identity", "camera at '" + id + "' has serial '" + got_serial + "', expected '" +
                                      want_serial + "'");
  }
  // Another application holding control (a second station, a vendor tool) would otherwise show as
  // a string of write timeouts or refusals in configure(); say so at once, naming the camera.
  if (const std::string problem = controlProblemLocked(cam.get(), got_serial, found_address.empty() ? id : found_address,
                                                       false);
      !problem.empty()) {
    throw fail("controlled", problem);
  }
  closeLocked();
  camera = std::move(cam);
  serial = got_serial;
  address = found_address;
  control_lost = false;
  lost_handler = glue::connectControlLost(arv_camera_get_device(camera.get()), &onControlLost, this);
  if (config) applyConfigLocked(*config);
}

std::string GigECamera::Impl::controlProblemLocked(ArvCamera* cam, const std::string& serial_text,
                                                   const std::string& where, bool confirm_by_write) {
  const std::string who = "camera " + serial_text + " at " + where;
  if (!glue::holdsControl(cam)) {
    std::uint32_t ccp = 0;
    // CCP bits 0 (exclusive) and 1 (control): someone holds the camera.
    if (glue::readControlPrivilege(cam, &ccp) && (ccp & 0x3) != 0) {
      return who + " is controlled by another application (CCP held)";
    }
    return who + " refused the control channel privilege (CCP write failed)";
  }
  if (confirm_by_write && arv_camera_is_gv_device(cam)) {
    ArvDevice* device = arv_camera_get_device(cam);
    guint32 timeout = 0;
    glue::Error e;
    // Heartbeat timeout (bootstrap 0x0938), written back unchanged: only the controller may write.
    if (arv_device_read_register(device, 0x0938, &timeout, e.out()) && !e &&
        !arv_device_write_register(device, 0x0938, timeout, e.out()) && e.isAccessDenied()) {
      return who + " is controlled by another application (CCP held)";
    }
  }
  return {};
}

void GigECamera::Impl::closeLocked(bool device_lost) noexcept {
  if (camera) glue::disconnectSignal(arv_camera_get_device(camera.get()), lost_handler);
  lost_handler = 0;
  if (device_lost) {
    try {
      glue::retireLostCamera(std::move(camera));
    } catch (const std::exception&) {  // no thread to be had: the rare race beats a leak
    }
  }
  camera.reset();
}

void GigECamera::Impl::applyConfigLocked(const CameraConfig& c) {
  ArvCamera* cam = camera.get();
  glue::Error e;
  auto check = [&](const std::string& feature, const std::string& value) {
    if (e) {
      const std::string msg = e.message();
      e.clear();
      throw owner.fault("config", "cannot set " + feature + " to " + value + ": " + msg);
    }
  };
  // Trigger off first: ROI and pixel format are locked on some cameras while armed.
  arv_camera_clear_triggers(cam, e.out());
  e.clear();  // cameras without trigger features
  gint sw = 0, sh = 0;
  arv_camera_get_sensor_size(cam, &sw, &sh, e.out());
  check("SensorWidth/SensorHeight", "(read)");
  const std::int64_t w = c.roi.width > 0 ? c.roi.width : sw - c.roi.x;
  const std::int64_t h = c.roi.height > 0 ? c.roi.height : sh - c.roi.y;
  arv_camera_set_region(cam, static_cast<gint>(c.roi.x), static_cast<gint>(c.roi.y), static_cast<gint>(w),
                        static_cast<gint>(h), e.out());
  check("OffsetX/OffsetY/Width/Height", std::to_string(c.roi.x) + "," + std::to_string(c.roi.y) + "," +
                                            std::to_string(w) + "x" + std::to_string(h));
  arv_camera_set_pixel_format_from_string(cam, c.pixel_format.c_str(), e.out());
  check("PixelFormat", c.pixel_format);
  // arv_camera_* pick ExposureTime or ExposureTimeAbs, Gain or GainRaw, whichever the device has.
  if (c.exposure_us) {
    arv_camera_set_exposure_time(cam, *c.exposure_us, e.out());
    check("ExposureTime", std::to_string(*c.exposure_us));
  }
  if (c.gain) {
    arv_camera_set_gain(cam, *c.gain, e.out());
    check("Gain", std::to_string(*c.gain));
  }
  if (c.packet_size) {
    arv_camera_gv_set_packet_size(cam, static_cast<gint>(*c.packet_size), e.out());
    check("GevSCPSPacketSize", std::to_string(*c.packet_size));
  }
  // Before the trigger: Aravis turns TriggerMode off when it sets the frame rate.
  if (c.frame_rate_hz) {
    arv_camera_set_frame_rate(cam, *c.frame_rate_hz, e.out());
    check("AcquisitionFrameRate", std::to_string(*c.frame_rate_hz));
  }
  if (c.trigger == TriggerMode::Software) {
    arv_camera_set_trigger(cam, "Software", e.out());  // FrameStart: TriggerMode=On, Source=Software
    check("TriggerMode/TriggerSource", "On/Software");
  }
}

void GigECamera::connectDevice() {
  std::lock_guard lock(impl_->camera_mutex);
  impl_->openLocked();
}

void GigECamera::disconnectDevice() noexcept {
  stopStreaming();
  std::lock_guard lock(impl_->camera_mutex);
  impl_->closeLocked(impl_->control_lost);
}

DeviceIdentity GigECamera::identifyDevice() {
  std::lock_guard lock(impl_->camera_mutex);
  ArvCamera* cam = impl_->camera.get();
  DeviceIdentity id;
  id.family = "camera";
  id.vendor = str(arv_camera_get_vendor_name(cam, nullptr));
  id.model = str(arv_camera_get_model_name(cam, nullptr));
  id.serial = impl_->serial;
  glue::Error e;
  id.firmware = str(arv_camera_get_string(cam, "DeviceVersion", e.out()));
  id.address = impl_->address;
  return id;
}

void GigECamera::checkDevice() {
  if (impl_->control_lost || !impl_->probeDevice()) throw fault("disconnected", "the camera does not answer GVCP");
  std::lock_guard lock(impl_->camera_mutex);
  if (!impl_->camera) return;
  const std::string problem = impl_->controlProblemLocked(
      impl_->camera.get(), impl_->serial, impl_->address.empty() ? options_.address : impl_->address, true);
  if (!problem.empty()) throw fault("controlled", problem);
}

bool GigECamera::Impl::probeDevice() {
  std::lock_guard lock(camera_mutex);
  if (!camera) return false;
  guint32 version = 0;
  glue::Error e;
  // Bootstrap register 0x0000 (GigE Vision version): every GigE Vision device has it.
  return arv_device_read_register(arv_camera_get_device(camera.get()), 0x0000, &version, e.out()) && !e;
}

void GigECamera::configure(const CameraConfig& config) {
  if (streaming()) throw fault("busy", "configure() while streaming; stop the stream first");
  std::lock_guard lock(impl_->camera_mutex);
  if (!impl_->camera) throw fault("disconnected", "configure() before connect()");
  impl_->applyConfigLocked(config);
  impl_->config = config;
}

CameraConfig GigECamera::readConfig() {
  std::lock_guard lock(impl_->camera_mutex);
  if (!impl_->camera) throw fault("disconnected", "readConfig() before connect()");
  ArvCamera* cam = impl_->camera.get();
  CameraConfig c;
  glue::Error e;
  gint x = 0, y = 0, w = 0, h = 0;
  arv_camera_get_region(cam, &x, &y, &w, &h, e.out());
  if (e) throw fault("config", "cannot read the region: " + e.message());
  c.roi = {x, y, w, h};
  c.pixel_format = str(arv_camera_get_pixel_format_as_string(cam, e.out()));
  e.clear();
  const double exposure = arv_camera_get_exposure_time(cam, e.out());
  if (!e) c.exposure_us = exposure;
  e.clear();
  const double gain = arv_camera_get_gain(cam, e.out());
  if (!e) c.gain = gain;
  e.clear();
  const guint packet = arv_camera_gv_get_packet_size(cam, e.out());
  if (!e) c.packet_size = packet;
  e.clear();
  const double rate = arv_camera_get_frame_rate(cam, e.out());
  if (!e) c.frame_rate_hz = rate;
  e.clear();
  const std::string mode = str(arv_camera_get_string(cam, "TriggerMode", e.out()));
  e.clear();
  const std::string source = str(arv_camera_get_string(cam, "TriggerSource", e.out()));
  c.trigger = mode == "On" && source == "Software" ? TriggerMode::Software : TriggerMode::FreeRun;
  return c;
}

std::vector<std::string> GigECamera::pixelFormats() {
  std::lock_guard lock(impl_->camera_mutex);
  if (!impl_->camera) throw fault("disconnected", "pixelFormats() before connect()");
  guint n = 0;
  glue::Error e;
  const char** names = arv_camera_dup_available_pixel_formats_as_strings(impl_->camera.get(), &n, e.out());
  std::vector<std::string> out;
  for (guint i = 0; names != nullptr && i < n; ++i) out.push_back(str(names[i]));
  g_free(static_cast<void*>(names));  // the array is ours, the strings are Aravis'
  return out;
}

std::pair<std::int64_t, std::int64_t> GigECamera::sensorSize() {
  std::lock_guard lock(impl_->camera_mutex);
  if (!impl_->camera) throw fault("disconnected", "sensorSize() before connect()");
  gint w = 0, h = 0;
  arv_camera_get_sensor_size(impl_->camera.get(), &w, &h, nullptr);
  return {w, h};
}

std::uint64_t GigECamera::softwareTrigger() {
  std::lock_guard lock(impl_->camera_mutex);
  if (!impl_->camera) throw fault("disconnected", "softwareTrigger() while the camera is not open");
  glue::Error e;
  impl_->last_trigger_ns = impl_->stationNow();
  arv_camera_software_trigger(impl_->camera.get(), e.out());
  if (e) throw fault("trigger", "TriggerSoftware failed: " + e.message());
  return ++impl_->triggers_issued;
}

void GigECamera::reconnect() {
  FrameCallback callback;
  {
    std::lock_guard lock(impl_->lifecycle_mutex);
    if (impl_->streaming) callback = impl_->callback;
  }
  stopStreaming();
  {
    std::lock_guard lock(impl_->camera_mutex);
    impl_->closeLocked(true);  // a reconnect is asked for when contact was in doubt
    impl_->openLocked();
  }
  {
    std::lock_guard lock(impl_->stats_mutex);
    ++impl_->stats.reconnects;
  }
  setState(DeviceState::Ready);
  if (callback) startStreaming(std::move(callback));
}

StreamStats GigECamera::stats() const {
  std::lock_guard lock(impl_->stats_mutex);
  return impl_->stats;
}

std::int64_t GigECamera::clockOffsetNs() const { return impl_->clock_offset_ns; }
ClockSyncMethod GigECamera::clockSyncMethod() const { return impl_->clock_method; }

}  // namespace stampscan::drivers::camera
