#include "stampscan/sim/virtual_digitizer.hpp"

#include <sys/ioctl.h>  // the _IO* macros usbdevice_fs.h builds its requests with
#include <linux/usbdevice_fs.h>
#include <umockdev.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <mutex>
#include <stdexcept>

namespace stampscan::sim {

using namespace drivers::digitizer;

namespace {

// Device descriptor (USB 2.0, class per interface, 64-byte ep0, 1d50:61a5, bcdDevice 1.00, strings
// 1-3, one configuration), configuration descriptor (one interface, bus-powered 500 mA), interface
// 0 (vendor class, one endpoint), endpoint 0x81 (bulk, 512 bytes). Hex as umockdev's "H:" wants it.
constexpr const char* kDescriptorsHex =
    "12010002000000" "40" "501d" "a561" "0001" "010203" "01"
    "0902190001010080fa"
    "090400000" "1ff000000"
    "07058102000200";

// What a reaped URB carries back: umockdev copies the changed local data back into the client.
struct Urb {
  UMockdevIoctlData* urb = nullptr;     // our reference to the client's struct usbdevfs_urb
  UMockdevIoctlData* buffer = nullptr;  // and to its data buffer
  int status = 0;
  int actual_length = 0;
  // umockdev holds a g_malloc()ed, suitably aligned local copy of the struct.
  usbdevfs_urb* get() const { return reinterpret_cast<usbdevfs_urb*>(urb->data); }
  void release() {
    if (buffer != nullptr) umockdev_ioctl_data_unref(buffer);
    if (urb != nullptr) umockdev_ioctl_data_unref(urb);
    buffer = urb = nullptr;
  }
};

}  // namespace

struct VirtualDigitizer::Impl {
  VirtualDigitizerOptions options;
  UMockdevTestbed* testbed = nullptr;
  UMockdevIoctlBase* handler = nullptr;
  std::string syspath;

  mutable std::mutex mutex;
  ProfileSource source = &VirtualDigitizer::testPattern;
  TimedProfileSource timed_source;  // when set, used instead of `source`
  DigitizerConfig config;
  bool streaming = false;
  std::uint32_t sequence = 0;
  std::uint32_t stream_first_sequence = 0;
  std::chrono::steady_clock::time_point stream_start;
  // Paced: one past the last profile the stream made before Stop. A real head exposes at its rate
  // into a buffer and still sends what it made after Stop, however late the host reaps it; the
  // simulator renders a profile only when it is reaped, so "made" is counted by the clock.
  std::uint32_t made_before_stop = 0;
  const std::chrono::steady_clock::time_point clock_zero = std::chrono::steady_clock::now();
  std::deque<Urb> control_done;  // answered control URBs, reaped first
  std::deque<Urb> bulk_posted;   // bulk-in URBs waiting for a profile
  std::deque<Urb> finished;      // discarded or torn-down URBs, reaped with their status
  bool stall_next = false, halted = false, silent = false, unplugged = false, mirror_fault = false;
  int drop = 0;
  std::uint64_t sent = 0, halts_cleared = 0;

  ~Impl() {
    for (auto* queue : {&control_done, &bulk_posted, &finished})
      for (Urb& u : *queue) u.release();
    if (handler != nullptr) g_object_unref(handler);
    if (testbed != nullptr) g_object_unref(testbed);
  }

  std::uint32_t statusWord() const {
    return (streaming ? kStatusStreaming : 0u) | (mirror_fault ? kStatusMirrorFault : 0u);
  }
  std::uint64_t deviceTime(std::uint32_t seq) const {
    return static_cast<std::uint64_t>(static_cast<double>(seq) * 1e9 / config.profile_rate_hz);
  }
  // Paced: one past the last profile made by now (the one being exposed counts as made: Stop
  // finishes it).
  std::uint32_t madeEnd() const {
    if (!streaming) return made_before_stop;
    const double since = std::chrono::duration<double>(std::chrono::steady_clock::now() - stream_start).count();
    return stream_first_sequence + static_cast<std::uint32_t>(std::floor(since * config.profile_rate_hz)) + 1;
  }
  std::uint64_t clockNow() const {
    return static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - clock_zero).count());
  }

  // Answers a control URB at submit time; the reply waits in control_done for the reap.
  void control(Urb& u) {
    usbdevfs_urb* urb = u.get();
    std::uint8_t* data = u.buffer->data;
    const std::size_t length = static_cast<std::size_t>(urb->buffer_length);
    u.status = -EPIPE;  // a control stall: what a device does with a request it refuses
    if (length < 8) return;
    const std::uint8_t type = data[0], request = data[1];
    const std::size_t w_length = std::min<std::size_t>(data[6] | (data[7] << 8), length - 8);
    std::uint8_t* payload = data + 8;
    auto reply = [&](const Bytes& bytes) {
      const std::size_t n = std::min(bytes.size(), w_length);
      std::memcpy(payload, bytes.data(), n);
      u.actual_length = static_cast<int>(n);
      u.status = 0;
    };
    if (type == kRequestTypeIn) {
      switch (static_cast<Request>(request)) {
        case Request::GetIdentity: reply(encode(options.identity)); break;
        case Request::GetConfig: {
          const float n = static_cast<float>(config.points_per_profile - 1);
          reply(encode(ConfigReply{config, -options.half_angle, 2 * options.half_angle / n}));
          break;
        }
        case Request::GetStatus:
          reply(encode(DeviceStatus{statusWord(), options.paced ? madeEnd() : sequence,
                                    options.paced ? clockNow() : deviceTime(sequence)}));
          break;
        default: break;
      }
    } else if (type == kRequestTypeOut) {
      switch (static_cast<Request>(request)) {
        case Request::SetConfig:
          if (streaming) return;
          try {
            config = decodeConfig(ByteView(payload, w_length));
          } catch (const ProtocolError&) {
            return;
          }
          u.status = 0;
          break;
        case Request::Start:
          if (!streaming) {
            // What the last stream made and the host never took is dropped with its buffer.
            if (options.paced) sequence = std::max(sequence, made_before_stop);
            streaming = true;
            stream_start = std::chrono::steady_clock::now();
            stream_first_sequence = sequence;
          }
          u.status = 0;
          break;
        case Request::Stop:
          if (streaming && options.paced) made_before_stop = madeEnd();
          streaming = false;
          u.status = 0;
          break;
        default: break;
      }
    }
  }

  // Fills the oldest posted bulk URB with the next profile; false when the device has nothing yet.
  bool produce(Urb& out) {
    if (bulk_posted.empty()) return false;
    if (stall_next) {
      stall_next = false;
      halted = true;
      out = bulk_posted.front();
      bulk_posted.pop_front();
      out.status = -EPIPE;
      out.actual_length = 0;
      return true;
    }
    if (halted || silent) return false;
    // Paced, a profile goes out once it is made, also after Stop (the head's buffer); unpaced, only
    // while streaming, as fast as the host reaps.
    if (options.paced ? sequence >= madeEnd() : !streaming) return false;
    Profile profile;
    for (; drop > 0; --drop) source(sequence++, config, profile);  // made, then lost on the wire
    profile = Profile{};
    // Paced, the profile was exposed when it fell due, however late the host reaps it: a real head
    // exposes at its rate and buffers.
    const auto exposure = options.paced ? stream_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                             std::chrono::duration<double>((sequence - stream_first_sequence) /
                                                                                           config.profile_rate_hz))
                                        : std::chrono::steady_clock::now();
    std::int64_t exposure_shift_ns = 0;
    if (timed_source)
      exposure_shift_ns = timed_source(sequence, config, exposure, profile);
    else
      source(sequence, config, profile);
    profile.sequence = sequence;
    const auto exposure_ns = static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(exposure - clock_zero).count() + exposure_shift_ns);
    profile.device_time_ns =
        options.paced ? exposure_ns + static_cast<std::uint64_t>(options.stamp_latency_ns) : deviceTime(sequence);
    if (mirror_fault) profile.status |= kStatusMirrorFault;
    ++sequence;
    const Bytes bytes = encode(profile);
    out = bulk_posted.front();
    bulk_posted.pop_front();
    if (bytes.size() > static_cast<std::size_t>(out.buffer->data_len)) {
      out.status = -EOVERFLOW;
      out.actual_length = 0;
      return true;
    }
    std::memcpy(out.buffer->data, bytes.data(), bytes.size());
    out.status = 0;
    out.actual_length = static_cast<int>(bytes.size());
    ++sent;
    return true;
  }

  void reap(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    Urb u;
    bool have = false;
    if (!finished.empty()) {
      u = finished.front(), finished.pop_front(), have = true;
    } else if (!control_done.empty()) {
      u = control_done.front(), control_done.pop_front(), have = true;
    } else if (unplugged) {
      umockdev_ioctl_client_complete(client, -1, ENODEV);
      return;
    } else {
      have = produce(u);
    }
    if (!have) {
      umockdev_ioctl_client_complete(client, -1, EAGAIN);
      return;
    }
    usbdevfs_urb* urb = u.get();
    urb->status = u.status;
    urb->actual_length = u.actual_length;
    UMockdevIoctlData* slot = umockdev_ioctl_data_resolve(arg, 0, sizeof(void*), nullptr);
    umockdev_ioctl_data_set_ptr(slot, 0, u.urb);  // the reaped URB pointer, in client terms
    umockdev_ioctl_data_unref(slot);
    u.release();
    umockdev_ioctl_client_complete(client, 0, 0);
  }

  void submit(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    Urb u;
    u.urb = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
    if (u.urb == nullptr) {
      umockdev_ioctl_client_complete(client, -1, EFAULT);
      return;
    }
    usbdevfs_urb* urb = u.get();
    if (urb->buffer_length > 0)
      u.buffer = umockdev_ioctl_data_resolve(u.urb, offsetof(usbdevfs_urb, buffer),
                                             static_cast<gsize>(urb->buffer_length), nullptr);
    if (urb->type == USBDEVFS_URB_TYPE_CONTROL && urb->endpoint == 0 && u.buffer != nullptr) {
      control(u);
      control_done.push_back(u);
    } else if (urb->type == USBDEVFS_URB_TYPE_BULK && urb->endpoint == kProfileEndpoint &&
               u.buffer != nullptr) {
      bulk_posted.push_back(u);
    } else {
      u.release();
      umockdev_ioctl_client_complete(client, -1, EINVAL);
      return;
    }
    umockdev_ioctl_client_complete(client, 0, 0);
  }

  void discard(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    gulong address = 0;  // DISCARDURB passes the URB pointer itself
    std::memcpy(&address, arg->data, sizeof address);
    for (auto it = bulk_posted.begin(); it != bulk_posted.end(); ++it) {
      if (it->urb->client_addr != address) continue;
      Urb u = *it;
      bulk_posted.erase(it);
      u.status = -ENOENT;  // what the kernel reports for a discarded URB
      u.actual_length = 0;
      finished.push_back(u);
      umockdev_ioctl_client_complete(client, 0, 0);
      return;
    }
    umockdev_ioctl_client_complete(client, -1, EINVAL);  // already completed
  }

  gboolean ioctl(UMockdevIoctlClient* client) {
    const gulong request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    std::lock_guard lock(mutex);
    if (unplugged && request != USBDEVFS_REAPURB && request != USBDEVFS_REAPURBNDELAY) {
      umockdev_ioctl_client_complete(client, -1, ENODEV);
      return TRUE;
    }
    switch (request) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* caps = umockdev_ioctl_data_resolve(arg, 0, sizeof(std::uint32_t), nullptr);
        // Scatter-gather: libusb then sends each bulk transfer as one URB, as for a modern kernel.
        const std::uint32_t bits = USBDEVFS_CAP_BULK_SCATTER_GATHER | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                                   USBDEVFS_CAP_ZERO_PACKET | USBDEVFS_CAP_REAP_AFTER_DISCONNECT;
        std::memcpy(caps->data, &bits, sizeof bits);
        umockdev_ioctl_data_unref(caps);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_RELEASEINTERFACE:
      case USBDEVFS_RESET:
      case USBDEVFS_RESETEP:
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      case USBDEVFS_CLEAR_HALT: {
        UMockdevIoctlData* ep = umockdev_ioctl_data_resolve(arg, 0, sizeof(unsigned), nullptr);
        unsigned endpoint = 0;
        std::memcpy(&endpoint, ep->data, sizeof endpoint);
        if (endpoint == kProfileEndpoint && halted) {
          halted = false;
          ++halts_cleared;
        }
        umockdev_ioctl_data_unref(ep);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_SUBMITURB: submit(client, arg); return TRUE;
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY: reap(client, arg); return TRUE;
      case USBDEVFS_DISCARDURB: discard(client, arg); return TRUE;
      default:
        umockdev_ioctl_client_complete(client, -1, ENOTTY);
        return TRUE;
    }
  }

  static gboolean onIoctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<Impl*>(self)->ioctl(client);
  }
};

VirtualDigitizer::VirtualDigitizer(VirtualDigitizerOptions options) : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.options = std::move(options);
  if (d.options.bus < 1 || d.options.bus > 127) throw std::invalid_argument("VirtualDigitizer: bus 1..127");
  encode(d.options.identity);  // throws ProtocolError on strings the protocol cannot carry
  char bus[8];
  std::snprintf(bus, sizeof bus, "%03d", d.options.bus);
  const std::string devnode = std::string("/dev/bus/usb/") + bus + "/001";
  d.syspath = "/sys/devices/usb" + std::to_string(d.options.bus);

  d.testbed = umockdev_testbed_new();
  d.handler = umockdev_ioctl_base_new();
  g_signal_connect_data(d.handler, "handle-ioctl", reinterpret_cast<GCallback>(&Impl::onIoctl), &d,
                        nullptr, static_cast<GConnectFlags>(0));
  // The handler first, so that the device node answers as soon as it exists.
  GError* error = nullptr;
  if (!umockdev_testbed_attach_ioctl(d.testbed, devnode.c_str(), d.handler, &error)) {
    const std::string why = error != nullptr ? error->message : "unknown error";
    g_clear_error(&error);
    throw std::runtime_error("VirtualDigitizer: attach ioctl handler to " + devnode + ": " + why);
  }
  const std::string record =
      "P: /devices/usb" + std::to_string(d.options.bus) + "\n"
      "N: bus/usb/" + bus + "/001\n"
      "E: SUBSYSTEM=usb\nE: DRIVER=usb\nE: DEVTYPE=usb_device\n"
      "E: BUSNUM=" + bus + "\nE: DEVNUM=001\nE: DEVNAME=" + devnode + "\n"
      "E: ID_VENDOR_ID=1d50\nE: ID_MODEL_ID=61a5\nE: ID_SERIAL_SHORT=" + d.options.identity.serial + "\n"
      "A: idVendor=1d50\\n\nA: idProduct=61a5\\n\nA: serial=" + d.options.identity.serial + "\\n\n"
      "A: bConfigurationValue=1\\n\nA: busnum=" + std::to_string(d.options.bus) + "\\n\n"
      "A: devnum=1\\n\nA: speed=480\\n\n"
      "H: descriptors=" + kDescriptorsHex + "\n";
  if (!umockdev_testbed_add_from_string(d.testbed, record.c_str(), &error)) {
    const std::string why = error != nullptr ? error->message : "unknown error";
    g_clear_error(&error);
    throw std::runtime_error("VirtualDigitizer: add device: " + why);
  }
}

VirtualDigitizer::~VirtualDigitizer() = default;

bool VirtualDigitizer::preloadActive() {
  // umockdev_in_mock_environment() answers false under umockdev-wrapper too (0.17), so look for the
  // preload library among the mapped objects of this process instead.
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
    if (line.find("libumockdev-preload") != std::string::npos) return true;
  return false;
}

void VirtualDigitizer::setTimedProfileSource(TimedProfileSource source) {
  std::lock_guard lock(impl_->mutex);
  impl_->timed_source = std::move(source);
}

void VirtualDigitizer::setProfileSource(ProfileSource source) {
  std::lock_guard lock(impl_->mutex);
  impl_->timed_source = nullptr;
  impl_->source = source ? std::move(source) : ProfileSource(&VirtualDigitizer::testPattern);
}

void VirtualDigitizer::testPattern(std::uint32_t sequence, const DigitizerConfig& config,
                                   Profile& profile) {
  const auto n = static_cast<std::size_t>(config.points_per_profile);
  profile.range.resize(n);
  profile.intensity.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t k = sequence * 31u + static_cast<std::uint32_t>(i);
    profile.range[i] = (k % 97 == 0) ? 0.0f : 80.0f + static_cast<float>(k % 4001) * 0.01f;
    profile.intensity[i] = static_cast<std::uint16_t>(k * 257u);
  }
  profile.status = kStatusOverexposed * (sequence % 50 == 49 ? 1u : 0u);
}

void VirtualDigitizer::stallEndpoint() {
  std::lock_guard lock(impl_->mutex);
  impl_->stall_next = true;
}

void VirtualDigitizer::setSilent(bool silent) {
  std::lock_guard lock(impl_->mutex);
  impl_->silent = silent;
}

void VirtualDigitizer::dropSequence(int count) {
  std::lock_guard lock(impl_->mutex);
  impl_->drop += count;
}

void VirtualDigitizer::unplug() {
  Impl& d = *impl_;
  std::lock_guard lock(d.mutex);
  if (d.unplugged) return;
  d.unplugged = true;
  d.streaming = false;
  // As the kernel does on disconnect: every URB in flight ends with -ESHUTDOWN (libusb: NO_DEVICE).
  for (Urb& u : d.bulk_posted) {
    u.status = -ESHUTDOWN;
    u.actual_length = 0;
    d.finished.push_back(u);
  }
  d.bulk_posted.clear();
  for (Urb& u : d.control_done) {
    u.status = -ESHUTDOWN;
    u.actual_length = 0;
    d.finished.push_back(u);
  }
  d.control_done.clear();
}

void VirtualDigitizer::setMirrorFault(bool on) {
  std::lock_guard lock(impl_->mutex);
  impl_->mirror_fault = on;
}

bool VirtualDigitizer::streaming() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->streaming;
}

DigitizerConfig VirtualDigitizer::config() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->config;
}

std::uint32_t VirtualDigitizer::nextSequence() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->options.paced ? impl_->madeEnd() : impl_->sequence;
}

std::uint64_t VirtualDigitizer::profilesSent() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->sent;
}

std::uint64_t VirtualDigitizer::haltsCleared() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->halts_cleared;
}

}  // namespace stampscan::sim
