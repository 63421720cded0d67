#include "stampscan/drivers/digitizer/usb_digitizer.hpp"

#include <libusb.h>

#include <atomic>
#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace stampscan::drivers::digitizer {
namespace {

std::string hex4(std::uint16_t v) {
  char text[8];
  std::snprintf(text, sizeof text, "%04x", v);
  return text;
}

// Bulk buffers are a whole number of 512-byte packets, at least one profile long: a device ends a
// profile with a short (or zero-length) packet, so a profile never spills into the next transfer.
int bulkBufferSize(int points) {
  const std::size_t size = profilePacketSize(points);
  return static_cast<int>((size / 512 + 1) * 512);
}

}  // namespace

struct UsbDigitizer::Impl {
  struct Slot {
    Impl* impl = nullptr;
    libusb_transfer* transfer = nullptr;
    std::vector<unsigned char> buffer;
  };

  explicit Impl(UsbDigitizer& o) : owner(o) {}

  static void LIBUSB_CALL onTransfer(libusb_transfer* transfer) {
    auto* slot = static_cast<Slot*>(transfer->user_data);
    slot->impl->completed(*slot);
  }

  UsbDigitizer& owner;
  libusb_context* ctx = nullptr;
  libusb_device_handle* handle = nullptr;
  bool claimed = false;
  Identity identity;
  std::string address;
  ConfigReply config;
  std::atomic<bool> gone{false};  // the device reported NO_DEVICE

  std::mutex control_mutex;  // one control request at a time, so replies cannot cross

  // Streaming. `mutex` guards the slots' submission state, the counters and the callbacks; the
  // profile callback itself runs outside it.
  mutable std::mutex mutex;
  ProfileCallback on_profile;
  FaultCallback on_fault;
  std::vector<std::unique_ptr<Slot>> slots;
  int in_flight = 0;
  bool stopping = false;
  bool silent = false;  // a timeout was reported and no profile has arrived since
  bool have_sequence = false;
  std::uint32_t last_sequence = 0;
  std::uint32_t first_sequence = 0;  // the stream's first profile's, read before Start
  DigitizerCounters counters;
  std::thread events;

  [[noreturn]] void controlFailed(Request request, int rc) {
    const std::string what = std::string(toString(request)) + ": ";
    if (rc == LIBUSB_ERROR_TIMEOUT) throw owner.fault("timeout", what + "no answer on endpoint 0");
    if (rc == LIBUSB_ERROR_NO_DEVICE) {
      gone = true;
      throw owner.fault("disconnected", what + "device gone");
    }
    if (rc == LIBUSB_ERROR_PIPE) throw owner.fault("protocol", what + "device refused the request");
    throw owner.fault("device-error", what + libusb_error_name(rc));
  }

  Bytes controlIn(Request request, std::size_t length) {
    if (handle == nullptr) throw owner.fault("disconnected", "not connected");
    std::lock_guard lock(control_mutex);
    Bytes reply(length);
    const int rc = libusb_control_transfer(
        handle, kRequestTypeIn, static_cast<std::uint8_t>(request), 0, kInterface, reply.data(),
        static_cast<std::uint16_t>(length), static_cast<unsigned>(owner.options_.control_timeout.count()));
    if (rc < 0) controlFailed(request, rc);
    reply.resize(static_cast<std::size_t>(rc));
    return reply;
  }

  void controlOut(Request request, Bytes data) {
    if (handle == nullptr) throw owner.fault("disconnected", "not connected");
    std::lock_guard lock(control_mutex);
    const int rc = libusb_control_transfer(
        handle, kRequestTypeOut, static_cast<std::uint8_t>(request), 0, kInterface, data.data(),
        static_cast<std::uint16_t>(data.size()),
        static_cast<unsigned>(owner.options_.control_timeout.count()));
    if (rc < 0) controlFailed(request, rc);
  }

  template <typename Decode>
  auto decodeReply(Request request, const Bytes& bytes, Decode decode) {
    try {
      return decode(ByteView(bytes));
    } catch (const ProtocolError& e) {
      throw owner.fault("protocol", std::string(toString(request)) + " reply: " + e.what());
    }
  }

  ConfigReply configure(const DigitizerConfig& wanted) {
    controlOut(Request::SetConfig, encode(wanted));
    ConfigReply reply = decodeReply(Request::GetConfig, controlIn(Request::GetConfig, kConfigReplySize),
                                    decodeConfigReply);
    if (reply.config.points_per_profile != wanted.points_per_profile ||
        reply.config.exposure_us != wanted.exposure_us)
      throw owner.fault("protocol", "GetConfig: the device did not take the configuration");
    config = reply;
    return reply;
  }

  void closeHandle() noexcept {
    if (handle != nullptr) {
      if (claimed) libusb_release_interface(handle, kInterface);
      libusb_close(handle);
    }
    handle = nullptr;
    claimed = false;
  }

  // Tries one candidate device; true when it is ours (open, claimed, identified, serial matches).
  bool tryOpen(libusb_device* device, std::string& why) {
    int rc = libusb_open(device, &handle);
    if (rc != 0) {
      why = std::string("open: ") + libusb_error_name(rc);
      handle = nullptr;
      return false;
    }
    rc = libusb_claim_interface(handle, kInterface);
    if (rc != 0) {
      why = std::string("claim interface 0: ") + libusb_error_name(rc);
      closeHandle();
      return false;
    }
    claimed = true;
    identity = decodeReply(Request::GetIdentity, controlIn(Request::GetIdentity, kIdentityMaxSize),
                           decodeIdentity);
    if (!owner.options_.serial.empty() && identity.serial != owner.options_.serial) {
      why = "serial " + identity.serial + " is not " + owner.options_.serial;
      closeHandle();
      return false;
    }
    address = "usb:" + hex4(owner.options_.vendor_id) + ":" + hex4(owner.options_.product_id) +
              " bus " + std::to_string(libusb_get_bus_number(device)) + " device " +
              std::to_string(libusb_get_device_address(device));
    return true;
  }

  // After Stop: waits until every profile the head made up to `made_end` (one past the last) has
  // arrived, while they keep arriving; what is still missing after drain_timeout without one is
  // counted lost (a sweep that lost its end must say so, not end early unnoticed).
  void receiveMadeProfiles(std::uint32_t made_end) {
    const auto timeout = owner.options_.drain_timeout;
    auto last_progress = std::chrono::steady_clock::now();
    std::uint64_t seen = 0;
    for (bool first = true;; first = false) {
      std::uint32_t missing = 0;
      {
        std::lock_guard lock(mutex);
        const std::uint32_t next = have_sequence ? last_sequence + 1 : first_sequence;
        const auto left = static_cast<std::int32_t>(made_end - next);  // modulo 2^32
        if (left <= 0 || gone || in_flight == 0) return;
        const auto now = std::chrono::steady_clock::now();
        if (first || counters.profiles != seen) {
          seen = counters.profiles;
          last_progress = now;
        } else if (now - last_progress >= timeout) {
          missing = static_cast<std::uint32_t>(left);
          counters.lost_profiles += missing;
          ++counters.sequence_gaps;
        }
      }
      if (missing > 0) {
        owner.reportFault("sequence-gap", std::to_string(missing) + " profile(s) the head made before Stop never arrived (none for " +
                                              std::to_string(timeout.count()) + " ms)");
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }

  void handlePacket(ByteView bytes) {
    Profile profile;
    try {
      profile = decodeProfile(bytes);
    } catch (const ProtocolError& e) {
      { std::lock_guard lock(mutex); ++counters.bad_packets; }
      owner.reportFault("protocol", std::string("profile packet dropped: ") + e.what());
      return;
    }
    std::uint32_t lost = 0;
    bool out_of_order = false;
    {
      std::lock_guard lock(mutex);
      silent = false;
      if (have_sequence) {
        // Unsigned difference: correct across the 2^32 wrap of the sequence counter.
        const std::uint32_t step = profile.sequence - last_sequence;
        if (step == 0 || step > 0x80000000u) out_of_order = true;
        else lost = step - 1;
      }
      if (!out_of_order) {
        have_sequence = true;
        last_sequence = profile.sequence;
        counters.lost_profiles += lost;
        if (lost > 0) ++counters.sequence_gaps;
        ++counters.profiles;
        counters.bytes += bytes.size();
      } else {
        ++counters.bad_packets;
      }
    }
    if (out_of_order) {
      owner.reportFault("protocol", "profile " + std::to_string(profile.sequence) +
                                        " out of order after " + std::to_string(last_sequence));
      return;
    }
    if (lost > 0)
      owner.reportFault("sequence-gap", std::to_string(lost) + " profile(s) lost before sequence " +
                                            std::to_string(profile.sequence));
    if (on_profile) on_profile(std::move(profile));
  }

  // Runs on the event thread for every finished bulk transfer.
  void completed(Slot& slot) {
    libusb_transfer* t = slot.transfer;
    bool resubmit = true;
    switch (t->status) {
      case LIBUSB_TRANSFER_COMPLETED:
        handlePacket(ByteView(t->buffer, static_cast<std::size_t>(t->actual_length)));
        break;
      case LIBUSB_TRANSFER_TIMED_OUT: {
        bool report = false;
        {
          std::lock_guard lock(mutex);
          ++counters.timeouts;
          report = !silent && !stopping;
          silent = true;
        }
        if (report)
          owner.reportFault("timeout", "no profile for " +
                                           std::to_string(owner.options_.transfer_timeout.count()) + " ms");
        break;
      }
      case LIBUSB_TRANSFER_STALL: {
        // A halted endpoint stays halted until the host clears it; clear_halt is a plain ioctl,
        // allowed from the callback.
        const int rc = libusb_clear_halt(handle, kProfileEndpoint);
        if (rc == 0) {
          std::lock_guard lock(mutex);
          ++counters.stalls_recovered;
        } else {
          resubmit = false;
          owner.reportFault(rc == LIBUSB_ERROR_NO_DEVICE ? "disconnected" : "stall",
                            std::string("clear halt on 0x81 failed: ") + libusb_error_name(rc));
        }
        break;
      }
      case LIBUSB_TRANSFER_NO_DEVICE:
        resubmit = false;
        if (!gone.exchange(true)) {
          owner.reportFault("disconnected", "the digitizer went away while streaming");
          cancelAll();
        }
        break;
      case LIBUSB_TRANSFER_CANCELLED:
        resubmit = false;
        break;
      case LIBUSB_TRANSFER_OVERFLOW:
        { std::lock_guard lock(mutex); ++counters.bad_packets; }
        owner.reportFault("protocol", "profile packet larger than the configured profile");
        break;
      case LIBUSB_TRANSFER_ERROR:
      default:
        resubmit = false;
        owner.reportFault("device-error", "bulk transfer failed; this transfer is given up");
        break;
    }
    bool vanished = false;
    {
      std::lock_guard lock(mutex);
      if (resubmit && !stopping && !gone) {
        const int rc = libusb_submit_transfer(t);
        if (rc == 0) return;
        vanished = rc == LIBUSB_ERROR_NO_DEVICE;
      }
      --in_flight;
    }
    // The device can vanish between a transfer's completion and its resubmission; then no transfer
    // ends with NO_DEVICE, and the resubmission is the only one to see it: it must report it too.
    if (vanished && !gone.exchange(true)) {
      owner.reportFault("disconnected", "the digitizer went away while streaming");
      cancelAll();
    }
  }

  void cancelAll() {
    std::lock_guard lock(mutex);
    for (auto& slot : slots) libusb_cancel_transfer(slot->transfer);  // NOT_FOUND when idle: fine
  }

  void eventLoop() {
    int errors = 0;
    for (;;) {
      {
        std::lock_guard lock(mutex);
        if (in_flight == 0) return;
      }
      timeval tv{0, 100000};
      const int rc = libusb_handle_events_timeout_completed(ctx, &tv, nullptr);
      if (rc < 0 && rc != LIBUSB_ERROR_INTERRUPTED && ++errors == 100) {
        // The event machinery itself is broken: give the transfers up rather than spin forever.
        owner.reportFault("device-error", std::string("libusb events: ") + libusb_error_name(rc));
        std::lock_guard lock(mutex);
        in_flight = 0;
        return;
      }
    }
  }
};

UsbDigitizer::UsbDigitizer(UsbDigitizerOptions options, std::string name)
    : Device(std::move(name)), options_(std::move(options)), impl_(std::make_unique<Impl>(*this)) {
  if (options_.transfers_in_flight < 1 || options_.transfers_in_flight > 64)
    throw std::invalid_argument("UsbDigitizer: transfers_in_flight must be 1..64");
  if (options_.control_timeout.count() <= 0 || options_.transfer_timeout.count() <= 0)
    throw std::invalid_argument("UsbDigitizer: timeouts must be positive");
  try {
    validate(options_.config);
  } catch (const ProtocolError& e) {
    throw std::invalid_argument(std::string("UsbDigitizer: ") + e.what());
  }
}

UsbDigitizer::~UsbDigitizer() { disconnectDevice(); }

void UsbDigitizer::connectDevice() {
  Impl& d = *impl_;
  d.gone = false;
  int rc = libusb_init(&d.ctx);
  if (rc != 0) {
    d.ctx = nullptr;
    throw fault("device-error", std::string("libusb_init: ") + libusb_error_name(rc));
  }
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(d.ctx, &list);
  std::string why = "no such device on the bus";
  bool found = false;
  for (ssize_t i = 0; i < count && !found; ++i) {
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(list[i], &desc) != 0) continue;
    if (desc.idVendor != options_.vendor_id || desc.idProduct != options_.product_id) continue;
    try {
      found = d.tryOpen(list[i], why);
    } catch (...) {
      d.closeHandle();
      libusb_free_device_list(list, 1);
      throw;
    }
  }
  if (count >= 0) libusb_free_device_list(list, 1);  // an empty bus still allocates the list
  if (!found) {
    throw fault("not-found", "USB " + hex4(options_.vendor_id) + ":" + hex4(options_.product_id) +
                                 (options_.serial.empty() ? "" : " serial " + options_.serial) +
                                 ": " + why);
  }
  d.configure(options_.config);
}

void UsbDigitizer::disconnectDevice() noexcept {
  stop();
  impl_->closeHandle();
  if (impl_->ctx != nullptr) libusb_exit(impl_->ctx);
  impl_->ctx = nullptr;
}

DeviceIdentity UsbDigitizer::identifyDevice() {
  const Identity& id = impl_->identity;
  return {"digitizer", "StampScan", id.model, id.serial, id.firmware, impl_->address};
}

void UsbDigitizer::checkDevice() {
  const DeviceStatus s = readStatus();
  if ((s.status_word & kStatusMirrorFault) != 0)
    throw DeviceError(name(), "device-error", "the digitizer reports a mirror fault");
}

ConfigReply UsbDigitizer::configure(const DigitizerConfig& config) {
  if (streaming()) throw DeviceError(name(), "busy", "configure: stop streaming first");
  try {
    validate(config);
  } catch (const ProtocolError& e) {
    throw std::invalid_argument(std::string("UsbDigitizer::configure: ") + e.what());
  }
  return impl_->configure(config);
}

ConfigReply UsbDigitizer::readConfig() {
  return impl_->decodeReply(Request::GetConfig, impl_->controlIn(Request::GetConfig, kConfigReplySize),
                            decodeConfigReply);
}

DeviceStatus UsbDigitizer::readStatus() {
  return impl_->decodeReply(Request::GetStatus, impl_->controlIn(Request::GetStatus, kStatusSize),
                            decodeStatus);
}


void UsbDigitizer::start(ProfileCallback on_profile) {
  Impl& d = *impl_;
  if (d.handle == nullptr) throw DeviceError(name(), "disconnected", "start: not connected");
  if (streaming()) throw DeviceError(name(), "busy", "start: already streaming");
  const int size = bulkBufferSize(d.config.config.points_per_profile);
  {
    std::lock_guard lock(d.mutex);
    d.on_profile = std::move(on_profile);
    d.stopping = false;
    d.silent = false;
    d.have_sequence = false;
    d.in_flight = 0;
    d.slots.clear();
    for (int i = 0; i < options_.transfers_in_flight; ++i) {
      auto slot = std::make_unique<Impl::Slot>();
      slot->impl = &d;
      slot->buffer.resize(static_cast<std::size_t>(size));
      slot->transfer = libusb_alloc_transfer(0);
      if (slot->transfer == nullptr) throw fault("device-error", "libusb_alloc_transfer failed");
      libusb_fill_bulk_transfer(slot->transfer, d.handle, kProfileEndpoint, slot->buffer.data(), size,
                                Impl::onTransfer, slot.get(),
                                static_cast<unsigned>(options_.transfer_timeout.count()));
      d.slots.push_back(std::move(slot));
    }
  }
  // Post the buffers before Start, so that the first profile finds one waiting.
  for (auto& slot : d.slots) {
    std::lock_guard lock(d.mutex);
    const int rc = libusb_submit_transfer(slot->transfer);
    if (rc != 0) {
      d.stopping = true;
      break;
    }
    ++d.in_flight;
  }
  d.events = std::thread([&d] { d.eventLoop(); });
  bool failed = false;
  { std::lock_guard lock(d.mutex); failed = d.stopping; }
  if (failed) {
    stop();
    throw fault("device-error", "start: could not submit the bulk transfers");
  }
  try {
    const DeviceStatus before = readStatus();
    {
      std::lock_guard lock(d.mutex);
      d.first_sequence = before.next_sequence;
    }
    d.controlOut(Request::Start, {});
  } catch (...) {
    stop();
    throw;
  }
  setState(DeviceState::Busy);
}

void UsbDigitizer::stop() noexcept {
  Impl& d = *impl_;
  if (!d.events.joinable()) return;
  if (!d.gone) {
    try {
      d.controlOut(Request::Stop, {});
      d.receiveMadeProfiles(readStatus().next_sequence);
    } catch (const std::exception&) {
      // Recorded by fault(); the transfers are cancelled below either way.
    }
  }
  {
    std::lock_guard lock(d.mutex);
    d.stopping = true;
  }
  d.cancelAll();
  d.events.join();
  std::lock_guard lock(d.mutex);
  for (auto& slot : d.slots) libusb_free_transfer(slot->transfer);
  d.slots.clear();
  d.on_profile = nullptr;
  if (state() == DeviceState::Busy) setState(DeviceState::Ready);
}

bool UsbDigitizer::streaming() const { return impl_->events.joinable(); }

void UsbDigitizer::setFaultCallback(FaultCallback callback) {
  std::lock_guard lock(impl_->mutex);
  impl_->on_fault = std::move(callback);
}

DigitizerCounters UsbDigitizer::counters() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->counters;
}

void UsbDigitizer::reportFault(const std::string& code, const std::string& text) {
  const DeviceError error = fault(code, text);
  FaultCallback callback;
  {
    std::lock_guard lock(impl_->mutex);
    callback = impl_->on_fault;
  }
  if (callback) callback({std::chrono::system_clock::now(), code, error.what()});
}

}  // namespace stampscan::drivers::digitizer
