#include "aravis_glue.hpp"

#include <arpa/inet.h>
#include <dirent.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <thread>

// GLib's type-checking macros expand to C casts; this file is the only one that uses them.
#pragma GCC diagnostic ignored "-Wold-style-cast"
#pragma GCC diagnostic ignored "-Wcast-function-type"

namespace stampscan::drivers::camera::glue {

void GObjectUnref::operator()(void* object) const noexcept {
  if (object != nullptr) g_object_unref(object);
}

Error::~Error() { clear(); }

void Error::clear() {
  if (error_ != nullptr) g_error_free(error_);
  error_ = nullptr;
}

std::string Error::message() const {
  return error_ != nullptr && error_->message != nullptr ? std::string(error_->message) : std::string();
}

bool Error::isAccessDenied() const {
  return error_ != nullptr && error_->domain == ARV_DEVICE_ERROR &&
         error_->code == ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED;
}

unsigned long connectControlLost(ArvDevice* device, void (*on_lost)(ArvDevice*, void*), void* user) {
  return g_signal_connect(device, "control-lost", G_CALLBACK(on_lost), user);
}

void disconnectSignal(ArvDevice* device, unsigned long handler) {
  if (device != nullptr && handler != 0) g_signal_handler_disconnect(device, handler);
}

namespace {
// Aravis' heartbeat (arvgvdeviceprivate.h, non-fast build): a check every second, retried for up to
// 5 s, each read up to its GVCP timeout and retries (2.5 s by default). A check begun before
// retirement has ended, emitting or not, within this.
constexpr std::chrono::seconds kHeartbeatCheckBound{12};

struct RetiredCamera {
  RetiredCamera() = default;
  RetiredCamera(const RetiredCamera&) = delete;
  RetiredCamera& operator=(const RetiredCamera&) = delete;
  ~RetiredCamera() {
    if (camera) disconnectSignal(arv_camera_get_device(camera.get()), handler);
  }
  GPtr<ArvCamera> camera;
  unsigned long handler = 0;
  std::mutex mutex;
  std::condition_variable emitted_cv;
  bool emitted = false;
};

void onRetiredControlLost(ArvDevice*, void* user) {
  auto* retired = static_cast<RetiredCamera*>(user);
  {
    std::lock_guard lock(retired->mutex);
    retired->emitted = true;
  }
  retired->emitted_cv.notify_all();
}
}  // namespace

void retireLostCamera(GPtr<ArvCamera> camera) {
  if (!camera) return;
  ArvDevice* device = arv_camera_get_device(camera.get());
  if (!ARV_IS_GV_DEVICE(device)) return;  // no heartbeat thread: dropping it now is safe
  auto retired = std::make_unique<RetiredCamera>();
  retired->camera = std::move(camera);
  retired->handler = connectControlLost(device, &onRetiredControlLost, retired.get());
  // Synchronously, as finalizing would: a camera that is still there is free for the reconnect.
  arv_gv_device_leave_control(ARV_GV_DEVICE(device), nullptr);
  // Detached: nothing waits for it, and it touches only what it owns. At process exit it may
  // still be waiting; the camera is then simply not finalized.
  std::thread([retired = std::move(retired)]() mutable {
    {
      std::unique_lock lock(retired->mutex);
      if (retired->emitted_cv.wait_for(lock, kHeartbeatCheckBound, [&] { return retired->emitted; })) {
        // The emission that woke us is still unwinding in the heartbeat thread; once it returns the
        // heartbeat no longer holds control and never emits again.
        lock.unlock();
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
      }
    }
    retired.reset();
  }).detach();
}

void setPacketResend(ArvStream* stream, bool enabled) {
  if (!ARV_IS_GV_STREAM(stream)) return;
  g_object_set(stream, "packet-resend",
               enabled ? ARV_GV_STREAM_PACKET_RESEND_ALWAYS : ARV_GV_STREAM_PACKET_RESEND_NEVER, NULL);
}

void setSocketBuffer(ArvStream* stream, int bytes) {
  if (!ARV_IS_GV_STREAM(stream)) return;
  // Aravis applies this when a frame begins, which is after the first frame's burst has met the
  // default buffer...
  g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size", bytes, NULL);
  // ... so the stream's socket (the UDP socket bound to its port; Aravis does not hand it out) gets
  // it now, before the first frame. With the packet socket (root, CAP_NET_RAW) there is none to find.
  const guint16 port = arv_gv_stream_get_port(ARV_GV_STREAM(stream));
  DIR* fds = ::opendir("/proc/self/fd");
  if (fds == nullptr) return;
  while (const dirent* entry = ::readdir(fds)) {
    char* end = nullptr;
    const long fd = std::strtol(entry->d_name, &end, 10);
    if (end == entry->d_name || *end != '\0' || fd == ::dirfd(fds)) continue;
    int type = 0;
    socklen_t type_length = sizeof type;
    sockaddr_storage address{};
    socklen_t address_length = sizeof address;
    if (::getsockopt(static_cast<int>(fd), SOL_SOCKET, SO_TYPE, &type, &type_length) != 0 || type != SOCK_DGRAM ||
        ::getsockname(static_cast<int>(fd), reinterpret_cast<sockaddr*>(&address), &address_length) != 0)
      continue;
    const guint16 bound = address.ss_family == AF_INET    ? ntohs(reinterpret_cast<const sockaddr_in*>(&address)->sin_port)
                          : address.ss_family == AF_INET6 ? ntohs(reinterpret_cast<const sockaddr_in6*>(&address)->sin6_port)
                                                          : 0;
    if (bound == port) ::setsockopt(static_cast<int>(fd), SOL_SOCKET, SO_RCVBUF, &bytes, sizeof bytes);
  }
  ::closedir(fds);
}

bool holdsControl(ArvCamera* camera) {
  ArvDevice* device = arv_camera_get_device(camera);
  return !ARV_IS_GV_DEVICE(device) || arv_gv_device_is_controller(ARV_GV_DEVICE(device));
}

bool readControlPrivilege(ArvCamera* camera, std::uint32_t* value) {
  guint32 ccp = 0;
  GError* error = nullptr;
  const bool ok = arv_device_read_register(arv_camera_get_device(camera), 0x0A00, &ccp, &error) && error == nullptr;
  if (error != nullptr) g_error_free(error);
  *value = ccp;
  return ok;
}

std::string findDeviceIdBySerial(const std::string& serial, std::string* address_out) {
  static std::mutex discovery_mutex;
  std::lock_guard lock(discovery_mutex);
  arv_update_device_list();
  const unsigned n = arv_get_n_devices();
  for (unsigned i = 0; i < n; ++i) {
    const char* s = arv_get_device_serial_nbr(i);
    if (s != nullptr && serial == s) {
      if (address_out != nullptr) {
        const char* a = arv_get_device_address(i);
        *address_out = a != nullptr ? a : "";
      }
      const char* id = arv_get_device_id(i);
      return id != nullptr ? id : "";
    }
  }
  return {};
}

}  // namespace stampscan::drivers::camera::glue
