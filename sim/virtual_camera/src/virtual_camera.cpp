#include "stampscan/sim/virtual_camera.hpp"

#include <arpa/inet.h>
#include <arv.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>

namespace stampscan::sim {

namespace {

bool isLoopback(const std::string& address) {
  in_addr a{};
  return inet_pton(AF_INET, address.c_str(), &a) == 1 && (ntohl(a.s_addr) >> 24) == 127;
}

bool addressOnLo(const std::string& address) {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return false;
  bool found = false;
  for (ifaddrs* i = list; i != nullptr && !found; i = i->ifa_next) {
    if (i->ifa_addr == nullptr || i->ifa_addr->sa_family != AF_INET) continue;
    char text[INET_ADDRSTRLEN] = {};
    sockaddr_in in{};
    std::memcpy(&in, i->ifa_addr, sizeof in);
    inet_ntop(AF_INET, &in.sin_addr, text, sizeof text);
    found = address == text && std::strcmp(i->ifa_name, "lo") == 0;
  }
  freeifaddrs(list);
  return found;
}

}  // namespace

struct VirtualCamera::Impl {
  mutable std::mutex mutex;  // guards source
  FrameSource source;
  std::atomic<std::uint64_t> filled{0};
  ArvGvFakeCamera* camera = nullptr;  // owned (g_object_unref in stop())
  double lost_ratio = 0.0;
  std::atomic<ArvFakeCamera*> fake{nullptr};  // the device model behind `camera`

  // The fake camera's fill-pattern hook (its streaming thread, under its fill-pattern mutex).
  static void fill(ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat format) {
    auto* self = static_cast<Impl*>(data);
    FrameRequest request;
    // Aravis 0.8.26 fills the buffer's image size only after this hook: read the registers the
    // fake camera has just used for this frame.
    guint32 width = 0, height = 0;
    ArvFakeCamera* fake = self->fake.load();
    if (fake == nullptr) return;
    arv_fake_camera_read_register(fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, &width);
    arv_fake_camera_read_register(fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &height);
    request.width = width;
    request.height = height;
    request.bytes_per_pixel = ARV_PIXEL_FORMAT_BIT_PER_PIXEL(format) > 8 ? 2 : 1;
    request.index = self->filled++;
    size_t size = 0;
    // The public API only hands out the buffer's data as const; the fake camera gives it to this
    // hook precisely to be written, as Aravis' own default pattern does.
    auto* bytes = static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, &size)));
    const std::size_t need = std::size_t{request.width} * request.height * request.bytes_per_pixel;
    // arv_buffer_get_data() reports the bytes received so far (0 here), not the capacity; the fake
    // camera only calls this hook after checking the buffer holds width * height * pixel size.
    if (bytes == nullptr || need > arv_fake_camera_get_payload(fake)) return;
    const std::span<std::uint8_t> out(bytes, need);
    FrameSource source;
    {
      std::lock_guard lock(self->mutex);
      source = self->source;
    }
    if (!source || !source(request, out)) testPattern(request, out);
  }
};

VirtualCamera::VirtualCamera(VirtualCameraOptions options)
    : options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  impl_->lost_ratio = options_.lost_packet_ratio;
}

VirtualCamera::~VirtualCamera() { stop(); }

void VirtualCamera::start() {
  if (impl_->camera != nullptr) return;
  if (!isLoopback(options_.address)) {
    throw std::runtime_error("virtual camera " + options_.serial + ": " + options_.address +
                             " is not a loopback address (127.0.0.0/8); refusing to listen on it");
  }
  if (!addressOnLo(options_.address)) {
    throw std::runtime_error("virtual camera " + options_.serial + ": " + options_.address +
                             " is not on lo (see VirtualCamera::ensureLoopbackAddress)");
  }
  ArvGvFakeCamera* camera = arv_gv_fake_camera_new_full(
      options_.address.c_str(), options_.serial.c_str(),
      options_.genicam_file.empty() ? nullptr : options_.genicam_file.c_str());
  if (camera == nullptr || !arv_gv_fake_camera_is_running(camera)) {
    if (camera != nullptr) g_object_unref(camera);
    throw std::runtime_error("virtual camera " + options_.serial + ": cannot serve GVCP on " + options_.address +
                             ":3956 (address missing, or port taken by another camera)");
  }
  impl_->fake = arv_gv_fake_camera_get_fake_camera(camera);
  arv_fake_camera_set_fill_pattern(impl_->fake, &Impl::fill, impl_.get());
  // In trigger mode the fake camera only looks for a trigger once per trigger period (25 Hz by
  // default), which would put up to 40 ms between the two cameras of one stereo trigger; a real
  // camera answers within microseconds.
  arv_fake_camera_set_trigger_frequency(impl_->fake, options_.trigger_poll_hz);
  g_object_set(camera, "gvsp-lost-ratio", impl_->lost_ratio, nullptr);
  impl_->camera = camera;
}

void VirtualCamera::stop() noexcept {
  if (impl_->camera == nullptr) return;
  g_object_unref(impl_->camera);  // joins the fake camera's thread, closes its sockets
  impl_->fake = nullptr;
  impl_->camera = nullptr;
}

bool VirtualCamera::running() const { return impl_->camera != nullptr; }

void VirtualCamera::setFrameSource(FrameSource source) {
  std::lock_guard lock(impl_->mutex);
  impl_->source = std::move(source);
}

void VirtualCamera::setLostPacketRatio(double ratio) {
  impl_->lost_ratio = ratio;
  // The fake camera's "gvsp-lost-ratio" property: each GVSP packet (leader, data, trailer) is
  // dropped with this probability before it is sent.
  if (impl_->camera != nullptr) g_object_set(impl_->camera, "gvsp-lost-ratio", ratio, nullptr);
}

std::uint64_t VirtualCamera::framesFilled() const { return impl_->filled; }

void VirtualCamera::testPattern(const FrameRequest& request, std::span<std::uint8_t> out) {
  for (std::uint32_t y = 0; y < request.height; ++y) {
    for (std::uint32_t x = 0; x < request.width; ++x) {
      const std::uint64_t v = x + y + request.index;
      const std::size_t at = (std::size_t{y} * request.width + x) * request.bytes_per_pixel;
      if (at + request.bytes_per_pixel > out.size()) return;
      out[at] = static_cast<std::uint8_t>(v);
      if (request.bytes_per_pixel == 2) out[at + 1] = static_cast<std::uint8_t>(v >> 8);
    }
  }
}

LoopbackStatus VirtualCamera::ensureLoopbackAddress(const std::string& address) {
  if (!isLoopback(address)) return {false, address + " is not a loopback address (127.0.0.0/8)"};
  if (addressOnLo(address)) return {true, ""};
  if (geteuid() != 0) {
    return {false, address + " is not on lo and adding it needs root: run `ip addr add " + address +
                       "/32 dev lo` as root"};
  }
  const std::string command = "ip addr add " + address + "/32 dev lo 2>&1";
  const int rc = std::system(command.c_str());
  if (rc != 0 || !addressOnLo(address)) {
    return {false, "`" + command + "` failed (exit " + std::to_string(WEXITSTATUS(rc)) +
                       "); is iproute2 installed and CAP_NET_ADMIN available?"};
  }
  return {true, ""};
}

}  // namespace stampscan::sim
