#include "stampscan/acquisition/safety_interlock.hpp"

namespace stampscan::acquisition {

using drivers::plc::PlcEventKind;

SafetyInterlock::SafetyInterlock(drivers::plc::ModbusPlc& plc, drivers::cmm::IppCmm& cmm) : cmm_(cmm) {
  plc.setEventCallback([this](const drivers::plc::PlcEvent& e) { onPlcEvent(e); });
}

void SafetyInterlock::onPlcEvent(const drivers::plc::PlcEvent& event) {
  const bool stop = event.kind == PlcEventKind::DoorOpened || event.kind == PlcEventKind::EStopBroken ||
                    event.kind == PlcEventKind::LightCurtainInterrupted || event.kind == PlcEventKind::InterlockTripped ||
                    event.kind == PlcEventKind::PlcSilent;
  // The driver's words for the operator ("door opened"), its code when it has none.
  std::string what = event.text.empty() ? drivers::plc::toString(event.kind) : event.text;
  if (stop) {
    // abort() is safe from another thread and returns at once; a CMM that is not moving ignores it.
    try {
      cmm_.abort();
      what += ": motion aborted";
    } catch (const std::exception& e) {
      what += std::string(": abort failed: ") + e.what();
    }
  }
  std::lock_guard lock(mutex_);
  if (stop) tripped_ = true;
  events_.push_back({event.when, what});
}

std::vector<SafetyEvent> SafetyInterlock::events() const {
  std::lock_guard lock(mutex_);
  return events_;
}

bool SafetyInterlock::tripped() const {
  std::lock_guard lock(mutex_);
  return tripped_;
}

void SafetyInterlock::reset() {
  std::lock_guard lock(mutex_);
  tripped_ = false;
}

}  // namespace stampscan::acquisition
