// The laser digitizer over USB (libusb). The same driver talks to the real head and to the virtual
// digitizer of sim/virtual_digitizer (a scripted USB device under umockdev); only the bus differs.
// The wire format is in digitizer_protocol.hpp and PROTOCOL.md.
//
// Streaming: start() submits `transfers_in_flight` bulk-in transfers on endpoint 0x81 and starts one
// event thread that runs libusb_handle_events; each completed transfer is decoded, checked and
// handed to the profile callback, then resubmitted. Several transfers in flight so that the host
// always has a buffer posted while it processes the last one: with one, the device would wait.
// Faults while streaming are recorded in the Device fault log (and passed to the fault callback):
//  - "sequence-gap": a profile's sequence number skipped ahead; the text names how many were lost;
//  - "stall": the endpoint halted; cleared with libusb_clear_halt and the transfer resubmitted;
//  - "timeout": no profile within transfer_timeout (reported once per silence, counted per transfer);
//  - "protocol": a packet that does not decode (counted, dropped);
//  - "disconnected": the device went away; every transfer is cancelled and the event thread ends.
//
// Thread safety: public methods may be called from any thread, but not from the callbacks. The
// callbacks run on the event thread; they must return quickly (the next transfer waits for them)
// and must not call stop(), disconnect() or destroy the driver.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "stampscan/drivers/device.hpp"
#include "stampscan/drivers/digitizer/digitizer_protocol.hpp"

namespace stampscan::drivers::digitizer {

struct UsbDigitizerOptions {
  std::uint16_t vendor_id = kVendorId;
  std::uint16_t product_id = kProductId;
  std::string serial;  // empty: the first device with vendor_id:product_id
  // Sent at connect; configure() changes it later.
  DigitizerConfig config;
  int transfers_in_flight = 4;
  std::chrono::milliseconds control_timeout{500};
  // A bulk transfer that sees no profile for this long ends with fault "timeout" and is resubmitted.
  std::chrono::milliseconds transfer_timeout{500};
  // After Stop the head still sends the profiles it made (GetStatus's next_sequence says how many):
  // stop() waits for them while they keep coming, and counts those still missing after this long
  // without one as lost.
  std::chrono::milliseconds drain_timeout{2000};
};

struct DigitizerCounters {
  std::uint64_t profiles = 0;        // delivered to the callback
  std::uint64_t bytes = 0;           // of delivered profiles
  std::uint64_t lost_profiles = 0;   // sum of the sequence gaps
  std::uint64_t sequence_gaps = 0;   // gap events
  std::uint64_t stalls_recovered = 0;
  std::uint64_t timeouts = 0;        // timed-out transfers
  std::uint64_t bad_packets = 0;
};

class UsbDigitizer : public Device {
 public:
  using ProfileCallback = std::function<void(Profile&& profile)>;
  using FaultCallback = std::function<void(const DeviceFault& fault)>;

  // Throws std::invalid_argument for options that cannot work (no transfers, a zero timeout, an
  // invalid config).
  explicit UsbDigitizer(UsbDigitizerOptions options = {}, std::string name = "digitizer");
  ~UsbDigitizer() override;

  // Sends SetConfig and reads back GetConfig. Not while streaming. Throws DeviceError: "protocol"
  // when the device refuses it (control stall) or answers nonsense, "timeout", "disconnected".
  ConfigReply configure(const DigitizerConfig& config);
  ConfigReply readConfig();
  DeviceStatus readStatus();

  // Starts streaming (state Busy): profiles go to `on_profile` on the event thread, in order.
  void start(ProfileCallback on_profile);
  // Sends Stop (unless the device is gone), cancels the transfers, joins the event thread; state
  // Ready (or stays Faulted). Idempotent.
  void stop() noexcept;
  bool streaming() const;
  void setFaultCallback(FaultCallback callback);
  DigitizerCounters counters() const;
  const UsbDigitizerOptions& options() const { return options_; }

 protected:
  void connectDevice() override;
  void disconnectDevice() noexcept override;
  DeviceIdentity identifyDevice() override;
  // GetStatus; throws DeviceError when the device does not answer or reports a mirror fault.
  void checkDevice() override;

 private:
  struct Impl;
  friend struct Impl;
  // Records a fault and hands it to the fault callback (event thread or caller).
  void reportFault(const std::string& code, const std::string& text);

  UsbDigitizerOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::drivers::digitizer
