// The client's side of one I++ DME connection: the TCP socket, the tags, and a reader thread that
// sorts every response line to the transaction or daemon it belongs to (§6.2.3, §6.2.4). It knows
// the wire format but not what the commands mean; IppCmm does that.
//
// Thread safety: every method may be called from any thread. Callbacks run on the reader thread,
// without the channel's lock held.
#pragma once

#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace stampscan::drivers::cmm::detail {

// What came back under one tag. Written by the reader thread until `complete`, then left alone, so
// the caller may read it once wait() returned Complete.
struct Transaction {
  ipp::Tag tag;
  std::string line;  // as sent, for messages
  bool acked = false;
  bool complete = false;
  std::vector<std::vector<ipp::Argument>> data;  // one entry per `#` line
  std::vector<ipp::ErrorReport> errors;          // one entry per `!` line
};

enum class WaitResult { Complete, Timeout, Lost };

class IppChannel {
 public:
  using LineHandler = std::function<void(const ipp::Reply&)>;
  struct Callbacks {
    LineHandler unsolicited;                          // lines tagged E0000 (§4.4, §6.2.4)
    std::function<void(const std::string&)> lost;    // the connection broke (never after close())
    std::function<void(const std::string&)> garbled;  // a line that is not a response, and why
  };

  // Connects to host:port within `connect_timeout` and starts the reader. Throws std::runtime_error
  // naming the address and the reason. `ack_wait` bounds how long a new command waits for the
  // previous one's Ack (§6.2.3: a new transaction only after the Ack of the previous one).
  IppChannel(const std::string& host, std::uint16_t port, std::chrono::milliseconds connect_timeout,
             std::chrono::milliseconds ack_wait, Callbacks callbacks);
  ~IppChannel();
  IppChannel(const IppChannel&) = delete;
  IppChannel& operator=(const IppChannel&) = delete;

  // Sends `name(args)` under a fresh command tag, or event tag when `event` (fast queue, §4).
  // `daemon` receives the `#` lines of the event tag, during and after the transaction, until
  // removeDaemon(). On a broken connection the transaction comes back Lost from wait().
  std::shared_ptr<Transaction> send(const std::string& name, std::vector<ipp::Argument> args, bool event,
                                    LineHandler daemon = {});
  // Waits for the Transaction complete (`%`). On Timeout the tag is forgotten: late lines for it are
  // dropped.
  WaitResult wait(const Transaction& transaction, std::chrono::steady_clock::time_point deadline);
  void removeDaemon(ipp::Tag tag);

  bool lost() const;
  std::string lostReason() const;
  std::uint64_t linesDropped() const;  // lines for tags nobody waits for any more
  // Shuts the socket and joins the reader; no `lost` callback follows. Idempotent.
  void close() noexcept;

 private:
  void readLoop();
  void dispatch(const ipp::Reply& reply);
  void markLost(const std::string& why);
  ipp::Tag allocateTag(bool event);  // with mutex_ held
  bool writeAll(const std::string& bytes);

  int fd_ = -1;
  std::chrono::milliseconds ack_wait_;
  Callbacks callbacks_;
  std::thread reader_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::map<ipp::Tag, std::shared_ptr<Transaction>> pending_;
  std::map<ipp::Tag, LineHandler> daemons_;
  int next_command_ = 1;
  int next_event_ = 1;
  bool lost_ = false;
  bool losing_ = false;  // markLost() is reporting; lost_ follows
  bool closing_ = false;
  std::string lost_reason_;
  std::uint64_t dropped_ = 0;
  std::string last_server_error_;  // the last error on E0000, for the reason of a lost connection

  std::mutex send_mutex_;  // one line at a time on the socket
};

}  // namespace stampscan::drivers::cmm::detail
