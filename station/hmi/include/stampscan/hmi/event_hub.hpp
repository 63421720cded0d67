// Live updates for the panel: events published by the scan's observer (and the server) and sent to
// every connected browser as Server-Sent Events. Each subscriber has its own bounded queue, so a
// slow or vanished browser never holds up the scan: its oldest events are dropped instead.
//
// Thread safety: every method may be called from any thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::hmi {

// One event as the browser receives it: `event: <name>` and `data: <json>`.
struct HubEvent {
  std::uint64_t id = 0;
  std::string name;
  std::string json;  // one line of JSON
};

class EventHub {
 public:
  class Subscription {
   public:
    // The next event, or nothing after `timeout` (the caller then sends a keep-alive) or once the
    // hub is closed (closed() says which).
    std::optional<HubEvent> next(std::chrono::milliseconds timeout);
    bool closed() const;

   private:
    friend class EventHub;
    mutable std::mutex mutex_;
    std::condition_variable ready_;
    std::deque<HubEvent> queue_;
    bool closed_ = false;
  };

  explicit EventHub(std::size_t queue_limit = 512) : queue_limit_(queue_limit) {}
  ~EventHub() { close(); }

  // `json` is a serialised JSON object; the hub adds "t_ms" (the publishing time, milliseconds of
  // the system clock) so that the page can measure how late it sees the event.
  void publish(const std::string& name, const std::string& json);
  std::shared_ptr<Subscription> subscribe();
  void unsubscribe(const std::shared_ptr<Subscription>& subscription);
  // Wakes every subscriber for good (the server is stopping).
  void close();

 private:
  std::size_t queue_limit_;
  mutable std::mutex mutex_;
  std::uint64_t next_id_ = 1;
  bool closed_ = false;
  std::vector<std::shared_ptr<Subscription>> subscribers_;
};

// The Server-Sent Events wire form of one event.
std::string formatServerSentEvent(const HubEvent& event);

}  // namespace stampscan::hmi
