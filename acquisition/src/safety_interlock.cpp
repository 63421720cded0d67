#include "stampscan/acquisition/safety_interlock.hpp"

namespace stampscan::acquisition {

using drivers::plc::PlcEventKind;

struct SafetyInterlock::State {
  explicit State(drivers::cmm::IppCmm& c) : cmm(c) {}
  void onPlcEvent(const drivers::plc::PlcEvent& event);

  drivers::cmm::IppCmm& cmm;
  mutable std::mutex mutex;
  std::vector<SafetyEvent> events;
  bool tripped = false;
};

SafetyInterlock::SafetyInterlock(drivers::plc::ModbusPlc& plc, drivers::cmm::IppCmm& cmm)
    : plc_(plc), state_(std::make_shared<State>(cmm)) {
  // The callback holds the state: the PLC's watchdog may still be delivering an event (it calls a
  // copy of the callback outside its lock) when this object goes away.
  plc.setEventCallback([state = state_](const drivers::plc::PlcEvent& e) { state->onPlcEvent(e); });
}

SafetyInterlock::~SafetyInterlock() { plc_.setEventCallback({}); }

void SafetyInterlock::State::onPlcEvent(const drivers::plc::PlcEvent& event) {
  const bool stop = event.kind == PlcEventKind::DoorOpened || event.kind == PlcEventKind::EStopBroken ||
                    event.kind == PlcEventKind::LightCurtainInterrupted || event.kind == PlcEventKind::InterlockTripped ||
                    event.kind == PlcEventKind::PlcSilent;
  // The driver's words for the operator ("door opened"), its code when it has none.
  const std::string what = event.text.empty() ? drivers::plc::toString(event.kind) : event.text;
  std::size_t index = 0;
  {
    // Recorded before the CMM is told: a move that ends aborted must find its cause here.
    std::lock_guard lock(mutex);
    if (stop) tripped = true;
    index = events.size();
    events.push_back({event.when, what, faultKindOf(event)});
  }
  if (!stop) return;
  // abort() is safe from another thread and returns at once; a CMM that is not moving ignores it.
  std::string outcome = ": motion aborted";
  try {
    cmm.abort();
  } catch (const std::exception& e) {
    outcome = std::string(": abort failed: ") + e.what();
  }
  std::lock_guard lock(mutex);
  events[index].what += outcome;
}

std::vector<SafetyEvent> SafetyInterlock::events() const {
  std::lock_guard lock(state_->mutex);
  return state_->events;
}

bool SafetyInterlock::tripped() const {
  std::lock_guard lock(state_->mutex);
  return state_->tripped;
}

void SafetyInterlock::reset() {
  std::lock_guard lock(state_->mutex);
  state_->tripped = false;
}

}  // namespace stampscan::acquisition
