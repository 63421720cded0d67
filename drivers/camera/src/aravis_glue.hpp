// The few places where the driver touches GLib's C macros (G_CALLBACK, GObject casts), kept in one
// file compiled with -Wold-style-cast relaxed, plus RAII owners for GObjects and GErrors. Only
// src/ includes this (Aravis stays out of the public headers).
#pragma once

#include <arv.h>

#include <cstdint>
#include <memory>
#include <string>

namespace stampscan::drivers::camera::glue {

struct GObjectUnref {
  void operator()(void* object) const noexcept;
};
template <typename T>
using GPtr = std::unique_ptr<T, GObjectUnref>;

// Owns the GError an Aravis call may set; `message()` is "" when there was none.
class Error {
 public:
  Error() = default;
  ~Error();
  Error(const Error&) = delete;
  Error& operator=(const Error&) = delete;
  GError** out() { return &error_; }
  explicit operator bool() const { return error_ != nullptr; }
  std::string message() const;
  // The camera answered with GEV_STATUS_ACCESS_DENIED (another application holds control).
  bool isAccessDenied() const;
  void clear();

 private:
  GError* error_ = nullptr;
};

// Connects `on_lost(user)` to the device's "control-lost" signal (emitted from Aravis' heartbeat
// thread); returns the handler id for disconnectSignal().
unsigned long connectControlLost(ArvDevice* device, void (*on_lost)(ArvDevice*, void*), void* user);
void disconnectSignal(ArvDevice* device, unsigned long handler);

// Lets go of a camera whose device may have lost contact (its stream went silent, its heartbeat
// failed). Dropping the last reference at once races Aravis' heartbeat thread: after its retries
// run out it emits "control-lost" on the device, and when that falls while the device is being
// finalized GLib refs a finalized object and the process crashes. So control is given up now (best
// effort: a write the camera may not answer) and the last reference is dropped on a short-lived
// thread once the heartbeat has emitted, or has certainly finished the check it may be in.
void retireLostCamera(GPtr<ArvCamera> camera);

// Resends make no sense against a device that ignores them (the fake camera) and are the
// device's business on a real one; the option lets the caller choose.
void setPacketResend(ArvStream* stream, bool enabled);
// The stream socket's receive buffer (SO_RCVBUF), in bytes. Without it the kernel's default
// (net.core.rmem_default, 208 KiB on Debian) holds less than one frame, and a process without
// CAP_NET_RAW (Aravis's packet socket needs it) loses the packets of a burst: a frame never
// completes. The kernel caps it at net.core.rmem_max.
void setSocketBuffer(ArvStream* stream, int bytes);

// GigE Vision control channel privilege (CCP, bootstrap register 0x0A00). Aravis writes CCP when it
// opens a GigE Vision camera and carries on without control when the camera refuses.
// True when Aravis holds control of `camera`, or when the camera is no GigE Vision device.
bool holdsControl(ArvCamera* camera);
// Reads CCP (any application may); false when the camera does not answer.
bool readControlPrivilege(ArvCamera* camera, std::uint32_t* value);

// Runs Aravis' global device discovery under a process-wide lock (the device list is global).
std::string findDeviceIdBySerial(const std::string& serial, std::string* address_out);

}  // namespace stampscan::drivers::camera::glue
