// The common part of every device driver (cameras, digitizer, CMM, PLC). As in libcamera's pipeline
// handlers, the public methods are non-virtual and own the shared work (state checks, fault log,
// counters); each device family implements only the protected *Device() hooks that talk to its
// hardware. The same driver runs against real hardware and against the virtual cell; only the
// address differs.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::drivers {

enum class DeviceState { Disconnected, Ready, Busy, Faulted };
const char* toString(DeviceState state);

struct DeviceIdentity {
  std::string family;    // "cmm", "plc", "camera", "digitizer"
  std::string vendor, model, serial, firmware;
  std::string address;   // how it was reached: "127.0.0.1:1294", "usb:1d6b:0104", ...
};

struct DeviceFault {
  std::chrono::system_clock::time_point when;
  std::string code;  // short, stable: "timeout", "protocol", "disconnected", "device-error", ...
  std::string text;  // what happened, for the operator
};

// Thrown by drivers; the message names the device and what failed.
class DeviceError : public std::runtime_error {
 public:
  DeviceError(const std::string& device, const std::string& code, const std::string& text)
      : std::runtime_error(device + ": " + text), code_(code) {}
  const std::string& code() const { return code_; }

 private:
  std::string code_;
};

class Device {
 public:
  explicit Device(std::string name) : name_(std::move(name)) {}
  virtual ~Device() = default;
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  // Connects and identifies the device; state Ready on success. Throws DeviceError (and records a
  // fault) on failure. Connecting a connected device reconnects it.
  void connect();
  void disconnect() noexcept;
  // A quick health check for `station devices`: true when the device answers and reports no fault.
  bool check();

  const std::string& name() const { return name_; }
  DeviceState state() const;
  DeviceIdentity identity() const;
  std::vector<DeviceFault> faults() const;
  void clearFaults();

 protected:
  virtual void connectDevice() = 0;
  virtual void disconnectDevice() noexcept = 0;
  virtual DeviceIdentity identifyDevice() = 0;
  // Asks the device for its own fault state; throws DeviceError when it does not answer.
  virtual void checkDevice() {}

  void setState(DeviceState state);
  // Records a fault (and sets Faulted); returns a DeviceError to throw.
  DeviceError fault(const std::string& code, const std::string& text);

 private:
  std::string name_;
  mutable std::mutex mutex_;
  DeviceState state_ = DeviceState::Disconnected;
  DeviceIdentity identity_;
  std::vector<DeviceFault> faults_;
};

}  // namespace stampscan::drivers
