// The GVCP side of a virtual camera: takes one request datagram and gives the acknowledge to send
// back, over Aravis' register-level fake camera (ArvFakeCamera). No sockets here: VirtualCamera
// feeds it what arrives on its UDP socket, the fuzz targets feed it arbitrary bytes.
//
// Every request is validated before it reaches ArvFakeCamera, whose memory accessors trust their
// caller (an out-of-range READMEM made Aravis' own GigE Vision server copy from a wild pointer):
// the header's length against the datagram, counts against the protocol's limits, alignment, and
// the address range against the register space and the GenICam XML. A bad request is answered
// with the GigE Vision status that names the problem (GEV_STATUS_INVALID_ADDRESS, _BAD_ALIGNMENT,
// _INVALID_PARAMETER, _INVALID_HEADER, _NOT_IMPLEMENTED, _WRITE_PROTECT, _ACCESS_DENIED), or
// dropped when it is not a GVCP command at all or asks for no acknowledge.
//
// Control channel privilege works as on a real camera: reads are open to every application
// (monitor access); writes need control, which one application at a time takes by writing CCP.
// Every command from the controller counts as its heartbeat; when none came within the heartbeat
// timeout (bootstrap register 0x0938), control is released and the stream channel closed.
//
// Thread safety: none. The caller serialises handle() and expireController() with every other use
// of the fake camera (VirtualCamera holds its device mutex).
#pragma once

#include <arv.h>

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <vector>

namespace stampscan::sim::gvcp {

// The camera's timestamp counter in ns (tick frequency 1 GHz, bootstrap 0x093C): the real-time
// clock, which Aravis' fake camera stamps its frames with, so that latched values and frame stamps
// are one clock.
inline std::uint64_t deviceTimeNs() { return static_cast<std::uint64_t>(g_get_real_time()) * 1000; }

struct Peer {
  std::uint32_t address = 0;  // IPv4, host byte order
  std::uint16_t port = 0;
  bool operator==(const Peer&) const = default;
};

// Where a request arrived: the camera's own address, or the broadcast discovery socket, where only
// DISCOVERY is served.
enum class Channel { Unicast, Discovery };

class Responder {
 public:
  // `camera` is borrowed and must outlive the responder.
  explicit Responder(ArvFakeCamera* camera);

  // Answers one request from `from` at `now_ms` (any monotonic millisecond clock). Returns the
  // acknowledge datagram; empty when nothing is to be sent back. Never throws on content.
  std::vector<std::uint8_t> handle(std::span<const std::uint8_t> request, const Peer& from, Channel channel,
                                   std::int64_t now_ms);

  // The software triggers written and not yet taken, oldest first: when each came, on the camera's
  // timestamp clock and the steady clock. Each makes one frame, however long the one before takes.
  struct Trigger {
    std::uint64_t device_ns = 0;
    std::chrono::steady_clock::time_point steady;
  };
  std::optional<Trigger> takeTrigger();
  void clearTriggers() { triggers_.clear(); }

  // Releases control when the controller's heartbeat ran out; true when it did.
  bool expireController(std::int64_t now_ms);
  std::optional<Peer> controller() const { return controller_; }

 private:
  struct Reply;
  void readRegisters(std::span<const std::uint8_t> payload, Reply& reply);
  void writeRegisters(std::span<const std::uint8_t> payload, const Peer& from, std::int64_t now_ms, Reply& reply);
  void readMemory(std::span<const std::uint8_t> payload, Reply& reply);
  void writeMemory(std::span<const std::uint8_t> payload, const Peer& from, Reply& reply);
  // The status a read of [address, address + count) gets; fills `out` on success.
  std::uint16_t readBytes(std::uint64_t address, std::uint32_t count, std::uint8_t* out);
  std::uint16_t writeRegister(std::uint32_t address, std::uint32_t value, const Peer& from, std::int64_t now_ms);
  std::uint16_t writableRange(std::uint64_t address, std::uint64_t count) const;
  bool isController(const Peer& from) const { return controller_ && *controller_ == from; }
  void releaseControl();

  ArvFakeCamera* camera_;
  std::vector<std::uint8_t> xml_;  // the GenICam XML, zero-padded to whole 32-bit words
  std::uint64_t xml_address_ = 0;  // where the bootstrap's XML URL says it lives
  std::optional<Peer> controller_;
  std::int64_t last_heartbeat_ms_ = 0;
  std::uint32_t default_heartbeat_ms_ = 3000;  // the model's heartbeat timeout at power-up
  std::deque<Trigger> triggers_;  // at most kMaxQueuedTriggers
};

}  // namespace stampscan::sim::gvcp
