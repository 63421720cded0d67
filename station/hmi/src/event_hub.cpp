#include "stampscan/hmi/event_hub.hpp"

#include <algorithm>

namespace stampscan::hmi {

std::optional<HubEvent> EventHub::Subscription::next(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  ready_.wait_for(lock, timeout, [&] { return closed_ || !queue_.empty(); });
  if (queue_.empty()) return std::nullopt;
  HubEvent e = std::move(queue_.front());
  queue_.pop_front();
  return e;
}

bool EventHub::Subscription::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

void EventHub::publish(const std::string& name, const std::string& json) {
  const auto now = std::chrono::duration_cast<std::chrono::milliseconds>(
                       std::chrono::system_clock::now().time_since_epoch()).count();
  HubEvent e;
  e.name = name;
  // The publishing time goes in as the object's first member; the payload is always an object.
  const std::string stamp = "\"t_ms\":" + std::to_string(now);
  e.json = json.size() > 2 ? "{" + stamp + "," + json.substr(1) : "{" + stamp + "}";
  std::lock_guard lock(mutex_);
  if (closed_) return;
  e.id = next_id_++;
  for (const auto& s : subscribers_) {
    std::lock_guard sl(s->mutex_);
    if (s->queue_.size() >= queue_limit_) s->queue_.pop_front();
    s->queue_.push_back(e);
    s->ready_.notify_one();
  }
}

std::shared_ptr<EventHub::Subscription> EventHub::subscribe() {
  auto s = std::make_shared<Subscription>();
  std::lock_guard lock(mutex_);
  s->closed_ = closed_;
  subscribers_.push_back(s);
  return s;
}

void EventHub::unsubscribe(const std::shared_ptr<Subscription>& subscription) {
  std::lock_guard lock(mutex_);
  std::erase(subscribers_, subscription);
}

void EventHub::close() {
  std::lock_guard lock(mutex_);
  closed_ = true;
  for (const auto& s : subscribers_) {
    std::lock_guard sl(s->mutex_);
    s->closed_ = true;
    s->ready_.notify_all();
  }
  subscribers_.clear();
}

std::string formatServerSentEvent(const HubEvent& event) {
  return "id: " + std::to_string(event.id) + "\nevent: " + event.name + "\ndata: " + event.json + "\n\n";
}

}  // namespace stampscan::hmi
