#include "stampscan/sim/virtual_camera.hpp"

#include <arpa/inet.h>
#include <arv.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <string>
#include <optional>
#include <span>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "gvcp_protocol.hpp"
#include "gvcp_responder.hpp"
#include "gvsp_sender.hpp"

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

namespace {

bool isLoopbackHost(std::uint32_t address) { return (address >> 24) == 127; }

// GigE Vision's timestamp latch as GenICam features (Standard Features Naming Convention names)
// over the bootstrap registers the responder serves: control 0x0944, latched value 0x0948 and the
// tick frequency 0x093C.
constexpr const char* kTimestampLatchFeatures = R"(
	<Command Name="GevTimestampControlLatch" NameSpace="Standard">
		<ToolTip>Latches the timestamp counter into GevTimestampValue</ToolTip>
		<pValue>GevTimestampControlRegister</pValue>
		<CommandValue>2</CommandValue>
	</Command>
	<IntReg Name="GevTimestampControlRegister" NameSpace="Custom">
		<Address>0x0944</Address>
		<Length>4</Length>
		<AccessMode>RW</AccessMode>
		<pPort>Device</pPort>
		<Cachable>NoCache</Cachable>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>
	<IntReg Name="GevTimestampValue" NameSpace="Standard">
		<ToolTip>The timestamp counter's value at the last latch, in ticks</ToolTip>
		<Address>0x0948</Address>
		<Length>8</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
		<Cachable>NoCache</Cachable>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>
	<IntReg Name="GevTimestampTickFrequency" NameSpace="Standard">
		<Address>0x093C</Address>
		<Length>8</Length>
		<AccessMode>RO</AccessMode>
		<pPort>Device</pPort>
		<Sign>Unsigned</Sign>
		<Endianess>BigEndian</Endianess>
	</IntReg>
)";

// Aravis' fake camera description with the timestamp latch added, in a file of its own (the model
// reads its description from a file when it is created); empty when the description is not as
// expected.
std::string fileWithTimestampLatch(const std::string& serial) {
  ArvFakeCamera* plain = arv_fake_camera_new(serial.c_str());
  if (plain == nullptr) return {};
  std::size_t size = 0;
  const char* xml = arv_fake_camera_get_genicam_xml(plain, &size);
  std::string text = xml != nullptr ? std::string(xml, size) : std::string();
  g_object_unref(plain);
  const std::size_t end = text.rfind("</RegisterDescription>");
  if (end == std::string::npos || text.find("GevTimestampValue") != std::string::npos) return {};
  text.insert(end, kTimestampLatchFeatures);
  std::string path = (std::filesystem::temp_directory_path() / "stampscan-camera-XXXXXX.xml").string();
  const int fd = ::mkstemps(path.data(), 4);
  if (fd < 0) return {};
  const bool written = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  ::close(fd);
  if (!written) {
    ::unlink(path.c_str());
    return {};
  }
  return path;
}

std::int64_t monotonicMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// An owned file descriptor.
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() { reset(); }
  Fd(Fd&& other) noexcept : fd_(other.release()) {}
  Fd& operator=(Fd&& other) noexcept {
    if (this != &other) {
      reset();
      fd_ = other.release();
    }
    return *this;
  }
  int get() const { return fd_; }
  explicit operator bool() const { return fd_ >= 0; }
  int release() { return std::exchange(fd_, -1); }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
};

sockaddr_in socketAddress(std::uint32_t host_order_address, std::uint16_t port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(host_order_address);
  a.sin_port = htons(port);
  return a;
}

// Confines a socket to packets that arrived on lo, whatever its bound address. Best effort: the
// caller decides whether it can do without.
bool bindToLoopbackDevice(int fd) {
  static constexpr char kLo[] = "lo";
  return setsockopt(fd, SOL_SOCKET, SO_BINDTODEVICE, kLo, sizeof kLo - 1) == 0;
}

// A real camera refuses out-of-range values when they are written; the model takes anything a
// controller writes and trusts it (a zero frame period divides by zero, a huge width overflows the
// payload). So a frame is only made from a configuration that holds together. Caller holds the
// device mutex.
bool frameConfigurationIsSound(ArvFakeCamera* camera) {
  constexpr std::size_t kMaxPayload = std::size_t{256} << 20;
  guint32 width = 0, height = 0, sensor_width = 0, sensor_height = 0, format = 0, period_us = 0;
  arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_WIDTH, &width);
  arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &height);
  arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, &sensor_width);
  arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, &sensor_height);
  arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, &format);
  arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US, &period_us);
  const std::size_t bits = ARV_PIXEL_FORMAT_BIT_PER_PIXEL(format);
  return width >= 1 && height >= 1 && width <= sensor_width && height <= sensor_height && bits >= 1 && bits <= 64 &&
         std::size_t{width} * height * ((bits + 7) / 8) <= kMaxPayload && period_us > 0 &&
         arv_fake_camera_get_payload(camera) <= kMaxPayload;
}

Fd udpSocket() { return Fd(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0)); }

}  // namespace

// The camera model (ArvFakeCamera: registers, GenICam XML, frame timing, trigger, image filling)
// is Aravis'; the network side is ours. Two threads per camera:
// - control: GVCP on the camera's address (UDP 3956) and broadcast discovery on lo, through
//   gvcp::Responder, which validates every request before the model sees it; it also expires the
//   controller's heartbeat;
// - stream: when a controller has opened the stream channel and started acquisition, fills frames
//   (free-run timing or software trigger, as the model says) and sends them as GVSP.
// device_mutex serialises every use of the model between them.
struct VirtualCamera::Impl {
  explicit Impl(const VirtualCameraOptions& o) : options(o) {}
  const VirtualCameraOptions& options;

  mutable std::mutex source_mutex;  // guards source
  FrameSource source;
  std::atomic<std::uint64_t> filled{0};
  std::atomic<double> lost_ratio{0.0};

  std::mutex device_mutex;            // guards camera and responder
  ArvFakeCamera* camera = nullptr;    // owned (g_object_unref in stop())
  std::atomic<ArvFakeCamera*> fake{nullptr};  // the same, for the fill hook
  std::optional<gvcp::Responder> responder;
  std::uint32_t address = 0;          // host order

  Fd gvcp_socket, discovery_socket, gvsp_socket, wake;
  std::thread control_thread, stream_thread;
  std::atomic<bool> stopping{false};
  std::mutex stream_wake_mutex;
  std::condition_variable stream_wake;
  bool stream_kicked = false;  // under stream_wake_mutex: the control thread changed something

  void openSockets();
  void runControl();
  void serveDatagram(int fd, gvcp::Channel channel, std::vector<std::uint8_t>& buffer);
  void kickStream();
  void runStream();

  // The fake camera's fill-pattern hook (our stream thread, under the fake camera's fill-pattern mutex).
  // Renders the next frame into `staged` without holding the device lock: a simulated world may
  // take a while to render, and the control channel (the controller's heartbeats among its
  // requests) must be served meanwhile, or a busy machine makes the controller lose the camera.
  // Stream thread only.
  void stageFrame(const FrameRequest& size) {
    FrameRequest request = size;
    request.index = filled++;
    staged.assign(std::size_t{request.width} * request.height * request.bytes_per_pixel, 0);
    FrameSource current;
    {
      std::lock_guard lock(source_mutex);
      current = source;
    }
    const std::span<std::uint8_t> out(staged.data(), staged.size());
    if (!current || !current(request, out)) testPattern(request, out);
    staged_request = request;
    staged_ready = true;
  }
  std::vector<std::uint8_t> staged;  // stream thread only (fill() runs on it too)
  FrameRequest staged_request;
  bool staged_ready = false;

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
    request.exposure = std::chrono::steady_clock::now();
    size_t size = 0;
    // The public API only hands out the buffer's data as const; the fake camera gives it to this
    // hook precisely to be written, as Aravis' own default pattern does.
    auto* bytes = static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, &size)));
    const std::size_t need = std::size_t{request.width} * request.height * request.bytes_per_pixel;
    // arv_buffer_get_data() reports the bytes received so far (0 here), not the capacity; the fake
    // camera only calls this hook after checking the buffer holds width * height * pixel size.
    if (bytes == nullptr || need > arv_fake_camera_get_payload(fake)) return;
    const std::span<std::uint8_t> out(bytes, need);
    // The image rendered beforehand, outside the device lock (runStream): copied, not made again.
    if (self->staged_ready && self->staged.size() == need && self->staged_request.width == request.width &&
        self->staged_request.height == request.height &&
        self->staged_request.bytes_per_pixel == request.bytes_per_pixel) {
      --self->filled;  // counted when it was staged
      std::copy(self->staged.begin(), self->staged.end(), out.begin());
      self->staged_ready = false;
      return;
    }
    self->staged_ready = false;
    FrameSource source;
    {
      std::lock_guard lock(self->source_mutex);
      source = self->source;
    }
    if (!source || !source(request, out)) testPattern(request, out);
  }
};

void VirtualCamera::Impl::openSockets() {
  const std::string where = "virtual camera " + options.serial + ": ";
  // GVCP: the camera's own loopback address only. No SO_REUSEADDR: a second server on the same
  // address must fail here rather than share (and steal) the requests.
  gvcp_socket = udpSocket();
  const sockaddr_in gvcp_address = socketAddress(address, gvcp::kPort);
  if (!gvcp_socket ||
      ::bind(gvcp_socket.get(), reinterpret_cast<const sockaddr*>(&gvcp_address), sizeof gvcp_address) != 0) {
    throw std::runtime_error(where + "cannot serve GVCP on " + options.address + ":3956: " + std::strerror(errno) +
                             " (address missing, or port taken by another camera)");
  }
  bindToLoopbackDevice(gvcp_socket.get());  // defence in depth: 127/8 never arrives elsewhere anyway

  // Broadcast discovery (what arv_update_device_list() and arv-tool send): a socket on
  // 255.255.255.255:3956, shared by the cameras of this host (SO_REUSEADDR) and bound to lo, so that
  // only broadcasts sent on this host's loopback reach it; it answers DISCOVERY and nothing else.
  // Without it a camera is still reachable by its address.
  discovery_socket = udpSocket();
  const int on = 1;
  const sockaddr_in broadcast = socketAddress(INADDR_BROADCAST, gvcp::kPort);
  if (!discovery_socket || setsockopt(discovery_socket.get(), SOL_SOCKET, SO_REUSEADDR, &on, sizeof on) != 0 ||
      !bindToLoopbackDevice(discovery_socket.get()) ||
      ::bind(discovery_socket.get(), reinterpret_cast<const sockaddr*>(&broadcast), sizeof broadcast) != 0) {
    std::fprintf(stderr, "%sno broadcast discovery on lo (%s); reachable by address only\n", where.c_str(),
                 std::strerror(errno));
    discovery_socket.reset();
  }

  // GVSP: sent from the camera's address, any port (advertised in SCSP).
  gvsp_socket = Fd(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  sockaddr_in gvsp_address = socketAddress(address, 0);
  socklen_t length = sizeof gvsp_address;
  if (!gvsp_socket ||
      ::bind(gvsp_socket.get(), reinterpret_cast<const sockaddr*>(&gvsp_address), sizeof gvsp_address) != 0 ||
      ::getsockname(gvsp_socket.get(), reinterpret_cast<sockaddr*>(&gvsp_address), &length) != 0) {
    throw std::runtime_error(where + "cannot open the GVSP socket on " + options.address + ": " + std::strerror(errno));
  }
  arv_fake_camera_write_register(camera, gvcp::kRegStreamSourcePort, ntohs(gvsp_address.sin_port));

  wake = Fd(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  if (!wake) throw std::runtime_error(where + "eventfd: " + std::strerror(errno));
}

void VirtualCamera::Impl::kickStream() {
  {
    std::lock_guard lock(stream_wake_mutex);
    stream_kicked = true;
  }
  stream_wake.notify_all();
}

void VirtualCamera::Impl::serveDatagram(int fd, gvcp::Channel channel, std::vector<std::uint8_t>& buffer) {
  sockaddr_in from{};
  socklen_t from_length = sizeof from;
  const ssize_t n =
      ::recvfrom(fd, buffer.data(), buffer.size(), 0, reinterpret_cast<sockaddr*>(&from), &from_length);
  if (n < 0 || from.sin_family != AF_INET) return;
  const gvcp::Peer peer{ntohl(from.sin_addr.s_addr), ntohs(from.sin_port)};
  if (!isLoopbackHost(peer.address)) return;  // only this host may talk to a virtual camera
  std::vector<std::uint8_t> reply;
  {
    std::lock_guard lock(device_mutex);
    reply = responder->handle(std::span(buffer.data(), static_cast<std::size_t>(n)), peer, channel, monotonicMs());
  }
  if (!reply.empty()) {
    // Always from the camera's own address, also for broadcast discoveries.
    (void)::sendto(gvcp_socket.get(), reply.data(), reply.size(), MSG_NOSIGNAL,
                   reinterpret_cast<const sockaddr*>(&from), from_length);
  }
  kickStream();  // a write may have started acquisition or fired the software trigger
}

void VirtualCamera::Impl::runControl() {
  std::vector<std::uint8_t> buffer(65536);  // any UDP datagram fits; a GVCP request is <= 548 bytes
  while (!stopping) {
    std::array<pollfd, 3> fds{{{gvcp_socket.get(), POLLIN, 0}, {wake.get(), POLLIN, 0}, {discovery_socket.get(), POLLIN, 0}}};
    const nfds_t count = discovery_socket ? 3 : 2;
    // The timeout bounds how late a controller whose heartbeat stopped is noticed.
    if (::poll(fds.data(), count, 100) > 0) {
      // Bounded batches, so that a flood on one socket cannot starve the other or the stop request.
      for (int i = 0; i < 64 && !stopping && (fds[0].revents & POLLIN) != 0; ++i) {
        serveDatagram(gvcp_socket.get(), gvcp::Channel::Unicast, buffer);
        pollfd again{gvcp_socket.get(), POLLIN, 0};
        if (::poll(&again, 1, 0) <= 0) break;
      }
      if (count == 3 && (fds[2].revents & POLLIN) != 0) {
        serveDatagram(discovery_socket.get(), gvcp::Channel::Discovery, buffer);
      }
    }
    bool expired = false;
    {
      std::lock_guard lock(device_mutex);
      expired = responder->expireController(monotonicMs());
    }
    if (expired) kickStream();
  }
}

void VirtualCamera::Impl::runStream() {
  gvsp::Sender sender(gvsp_socket.get());
  std::vector<std::uint8_t> image;  // the frame memory, lent to the ArvBuffer the model fills
  ArvBuffer* buffer = nullptr;      // owned; wraps `image`
  std::optional<guint64> next_frame_us;  // free-run: when the model says the next frame is due
  std::uint16_t block_id = 0;
  bool streaming = false;
  const auto poll_period = std::chrono::microseconds(
      static_cast<std::int64_t>(1e6 / std::max(options.trigger_poll_hz, 1.0)));

  while (!stopping) {
    std::chrono::microseconds wait = std::chrono::milliseconds(100);
    bool due = false;
    gvsp::BlockInfo info;
    FrameRequest render;
    std::uint64_t exposed_ns = 0;  // the frame's timestamp: when its exposure started
    std::optional<gvcp::Responder::Trigger> trigger;  // the software trigger it answers
    gvsp::Destination to;
    std::uint32_t packet_size = 0;
    std::size_t payload = 0;
    {
      std::lock_guard lock(device_mutex);
      guint32 port = 0, destination = 0;
      arv_fake_camera_read_register(camera, gvcp::kRegStreamHostPort, &port);
      arv_fake_camera_read_register(camera, gvcp::kRegStreamDestination, &destination);
      to = {destination, static_cast<std::uint16_t>(port & 0xFFFF)};
      // Stream only to a controller on this host: a virtual camera never sends onto a network.
      const bool open = arv_fake_camera_get_control_channel_privilege(camera) != 0 &&
                        arv_fake_camera_get_acquisition_status(camera) != 0 && to.port != 0 &&
                        isLoopbackHost(to.address) && frameConfigurationIsSound(camera);
      if (!open) {
        streaming = false;
        next_frame_us.reset();
        responder->clearTriggers();  // a trigger with no stream to send its frame to is lost
      } else {
        if (!streaming) block_id = 0;  // a new acquisition starts at block id 1, as real cameras do
        streaming = true;
        if (arv_fake_camera_is_in_free_running_mode(camera)) {
          if (!next_frame_us) arv_fake_camera_get_sleep_time_for_next_frame(camera, &next_frame_us.emplace());
          const auto now_us = static_cast<guint64>(g_get_real_time());
          due = now_us >= *next_frame_us;
          if (due) {
            next_frame_us.reset();
          } else {
            wait = std::chrono::microseconds(static_cast<std::int64_t>(*next_frame_us - now_us));
          }
        } else if (arv_fake_camera_is_in_software_trigger_mode(camera)) {
          // One frame per trigger written (the responder queues them); the model's own flag only
          // says that there was one.
          (void)arv_fake_camera_check_and_acknowledge_software_trigger(camera);
          trigger = responder->takeTrigger();
          due = trigger.has_value();
          wait = poll_period;  // the control thread wakes us at once when a trigger is written
        }
      }
      if (due) {
        guint32 format = 0;
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_WIDTH, &info.width);
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &info.height);
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, &format);
        render.width = info.width;
        render.height = info.height;
        render.bytes_per_pixel = ARV_PIXEL_FORMAT_BIT_PER_PIXEL(format) > 8 ? 2 : 1;
        // A triggered exposure starts with its trigger, a free-running one now.
        exposed_ns = trigger ? trigger->device_ns : gvcp::deviceTimeNs();
        render.exposure = trigger ? trigger->steady : std::chrono::steady_clock::now();
      }
    }
    if (due) {
      stageFrame(render);

      std::lock_guard lock(device_mutex);
      {
        payload = arv_fake_camera_get_payload(camera);
        if (payload > image.size() || buffer == nullptr) {
          if (buffer != nullptr) g_object_unref(buffer);
          image.assign(std::max(payload, image.size()), 0);
          buffer = arv_buffer_new(image.size(), image.data());
        }
        arv_fake_camera_fill_buffer(camera, buffer, nullptr);
        guint32 value = 0;
        arv_fake_camera_read_register(camera, gvcp::kRegStreamPacketSize, &value);
        packet_size = value & 0xFFFF;
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_WIDTH, &info.width);
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &info.height);
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_X_OFFSET, &info.offset_x);
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_Y_OFFSET, &info.offset_y);
        arv_fake_camera_read_register(camera, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, &info.pixel_format);
        // Stamped with the exposure's start, as a camera latches its counter at the frame start,
        // not when the image was made (the fake camera stamps the fill).
        info.timestamp = exposed_ns;
        due = arv_buffer_get_status(buffer) == ARV_BUFFER_STATUS_SUCCESS;
      }
    }
    if (due) {
      block_id = gvsp::nextBlockId(block_id);
      info.block_id = block_id;
      sender.sendBlock(info, std::span(image.data(), payload), to, packet_size, lost_ratio.load());
      continue;
    }
    std::unique_lock lock(stream_wake_mutex);
    stream_wake.wait_for(lock, wait, [this] { return stream_kicked || stopping.load(); });
    stream_kicked = false;
  }
  if (buffer != nullptr) g_object_unref(buffer);
}

VirtualCamera::VirtualCamera(VirtualCameraOptions options)
    : options_(std::move(options)), impl_(std::make_unique<Impl>(options_)) {
  impl_->lost_ratio = options_.lost_packet_ratio;
}

VirtualCamera::~VirtualCamera() { stop(); }

void VirtualCamera::start() {
  if (impl_->camera != nullptr) return;
  in_addr parsed{};
  if (!isLoopback(options_.address) || inet_pton(AF_INET, options_.address.c_str(), &parsed) != 1) {
    throw std::runtime_error("virtual camera " + options_.serial + ": " + options_.address +
                             " is not a loopback address (127.0.0.0/8); refusing to listen on it");
  }
  if (!addressOnLo(options_.address)) {
    throw std::runtime_error("virtual camera " + options_.serial + ": " + options_.address +
                             " is not on lo (see VirtualCamera::ensureLoopbackAddress)");
  }
  // The description: the one given, else Aravis' own, with the timestamp latch unless left out.
  std::string description = options_.genicam_file;
  const std::string latch_file =
      description.empty() && options_.timestamp_latch ? fileWithTimestampLatch(options_.serial) : std::string();
  if (description.empty()) description = latch_file;
  ArvFakeCamera* camera =
      arv_fake_camera_new_full(options_.serial.c_str(), description.empty() ? nullptr : description.c_str());
  if (!latch_file.empty()) ::unlink(latch_file.c_str());  // read when the model was made
  if (camera == nullptr) {
    throw std::runtime_error("virtual camera " + options_.serial + ": Aravis cannot create the camera model" +
                             (options_.genicam_file.empty() ? std::string() : " from " + options_.genicam_file));
  }
  Impl& d = *impl_;
  d.camera = camera;
  d.address = ntohl(parsed.s_addr);
  // What the bootstrap registers tell a discovering host: our address (current IP configuration)
  // and a locally administered MAC address made from it (02:00 + the IPv4 address).
  arv_fake_camera_write_register(camera, 0x0024, d.address);     // current IP address
  arv_fake_camera_write_register(camera, 0x0034, 0xFF000000u);   // current subnet mask
  arv_fake_camera_write_register(camera, gvcp::kRegMacHigh, 0x0200);
  arv_fake_camera_write_register(camera, gvcp::kRegMacLow, d.address);
  if (options_.sensor_width > 0 && options_.sensor_height > 0) {
    const auto width = static_cast<guint32>(options_.sensor_width), height = static_cast<guint32>(options_.sensor_height);
    arv_fake_camera_write_register(camera, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, width);
    arv_fake_camera_write_register(camera, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, height);
    arv_fake_camera_write_register(camera, ARV_FAKE_CAMERA_REGISTER_WIDTH, width);
    arv_fake_camera_write_register(camera, ARV_FAKE_CAMERA_REGISTER_HEIGHT, height);
  }
  arv_fake_camera_set_fill_pattern(camera, &Impl::fill, impl_.get());
  // In software-trigger mode the stream thread is woken by the trigger write itself; this is only
  // the model's own polling period, kept short in case a wake-up is missed.
  arv_fake_camera_set_trigger_frequency(camera, options_.trigger_poll_hz);
  d.fake = camera;
  d.responder.emplace(camera);
  try {
    d.openSockets();
  } catch (...) {
    stop();
    throw;
  }
  d.stopping = false;
  d.control_thread = std::thread([&d] { d.runControl(); });
  d.stream_thread = std::thread([&d] { d.runStream(); });
}

void VirtualCamera::stop() noexcept {
  Impl& d = *impl_;
  if (d.camera == nullptr) return;
  d.stopping = true;
  if (d.wake) {
    const std::uint64_t one = 1;
    (void)::write(d.wake.get(), &one, sizeof one);
  }
  d.kickStream();
  if (d.control_thread.joinable()) d.control_thread.join();
  if (d.stream_thread.joinable()) d.stream_thread.join();
  d.gvcp_socket.reset();  // as if unplugged: the port is free again at once
  d.discovery_socket.reset();
  d.gvsp_socket.reset();
  d.wake.reset();
  d.responder.reset();
  d.fake = nullptr;
  g_object_unref(d.camera);
  d.camera = nullptr;
}

bool VirtualCamera::running() const { return impl_->camera != nullptr; }

void VirtualCamera::setFrameSource(FrameSource source) {
  std::lock_guard lock(impl_->source_mutex);
  impl_->source = std::move(source);
}

void VirtualCamera::setLostPacketRatio(double ratio) {
  // Each GVSP packet (leader, payload, trailer) is dropped with this probability before it is sent.
  impl_->lost_ratio = std::clamp(ratio, 0.0, 1.0);
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
