#include "stampscan/drivers/device.hpp"

namespace stampscan::drivers {

const char* toString(DeviceState state) {
  switch (state) {
    case DeviceState::Disconnected: return "disconnected";
    case DeviceState::Ready: return "ready";
    case DeviceState::Busy: return "busy";
    case DeviceState::Faulted: return "faulted";
  }
  return "unknown";
}

void Device::connect() {
  disconnect();
  try {
    connectDevice();
    const DeviceIdentity id = identifyDevice();
    std::lock_guard lock(mutex_);
    identity_ = id;
    state_ = DeviceState::Ready;
  } catch (const DeviceError&) {
    disconnectDevice();
    setState(DeviceState::Faulted);
    throw;
  } catch (const std::exception& e) {
    disconnectDevice();
    throw fault("connect", e.what());
  }
}

void Device::disconnect() noexcept {
  disconnectDevice();
  std::lock_guard lock(mutex_);
  state_ = DeviceState::Disconnected;
}

bool Device::check() {
  if (state() == DeviceState::Disconnected) return false;
  try {
    checkDevice();
  } catch (const DeviceError&) {
    return false;
  }
  std::lock_guard lock(mutex_);
  return state_ != DeviceState::Faulted;
}

DeviceState Device::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

DeviceIdentity Device::identity() const {
  std::lock_guard lock(mutex_);
  return identity_;
}

std::vector<DeviceFault> Device::faults() const {
  std::lock_guard lock(mutex_);
  return faults_;
}

void Device::clearFaults() {
  std::lock_guard lock(mutex_);
  faults_.clear();
  if (state_ == DeviceState::Faulted) state_ = DeviceState::Ready;
}

void Device::setState(DeviceState state) {
  std::lock_guard lock(mutex_);
  state_ = state;
}

DeviceError Device::fault(const std::string& code, const std::string& text) {
  std::lock_guard lock(mutex_);
  faults_.push_back({std::chrono::system_clock::now(), code, text});
  state_ = DeviceState::Faulted;
  return DeviceError(name_, code, text);
}

}  // namespace stampscan::drivers
