#include "gvcp_responder.hpp"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>
#include <string>

#include "gvcp_protocol.hpp"

namespace stampscan::sim::gvcp {

namespace {

// ArvFakeCamera keeps its registers in ARV_FAKE_CAMERA_MEMORY_SIZE bytes of plain memory and checks
// "address + size < size of memory" (strictly): keep one word clear of the end.
constexpr std::uint64_t kRegisterSpaceEnd = ARV_FAKE_CAMERA_MEMORY_SIZE - 4;

// The fake camera's acquisition register (AcquisitionStart/Stop write it; not a bootstrap register).
constexpr std::uint32_t kRegAcquisition = ARV_FAKE_CAMERA_REGISTER_ACQUISITION;

// Bootstrap registers a real device makes read-only: identity (version, device mode, MAC address,
// IP capabilities, current IP configuration, manufacturer, model, version, info, serial number),
// channel counts and capabilities, the timestamp tick frequency; and the model's sensor size, which
// bounds every image. Of the XML URLs (0x0200 and 0x0400, 512 bytes each) only the first half of
// URL 0 and URL 1 are protected, because the fake camera's GenICam description puts its trigger
// registers at 0x0300.
// A camera buffers a few triggers while it still makes a frame; more are dropped, as a real
// camera's overrun.
constexpr std::size_t kMaxQueuedTriggers = 16;

struct Range {
  std::uint32_t begin, end;  // [begin, end)
};
constexpr std::array<Range, 9> kReadOnly{{{0x0000, 0x0014},
                                          {0x0024, 0x00E8},
                                          {0x0200, 0x0300},
                                          {0x0400, 0x0600},
                                          {ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH + 4},
                                          {0x0900, 0x090C},
                                          {0x092C, 0x0938},
                                          {0x093C, 0x0944},
                                          {kRegTimestampValueHigh, kRegTimestampValueLow + 4}}};

// Where "Local:<name>;<hex address>;<hex size>" puts the GenICam XML; 0 when it cannot be read.
std::uint64_t xmlAddressFromUrl(const std::string& url) {
  if (url.rfind("Local:", 0) != 0) return 0;
  const std::size_t first = url.find(';');
  if (first == std::string::npos) return 0;
  char* end = nullptr;
  const unsigned long long address = std::strtoull(url.c_str() + first + 1, &end, 16);
  return end != nullptr && *end == ';' ? address : 0;
}

}  // namespace

struct Responder::Reply {
  std::uint16_t status = GEV_STATUS_SUCCESS;
  std::uint16_t answer = 0;
  std::vector<std::uint8_t> payload;
};

Responder::Responder(ArvFakeCamera* camera) : camera_(camera) {
  std::size_t size = 0;
  const char* xml = arv_fake_camera_get_genicam_xml(camera_, &size);
  if (xml != nullptr) {
    // Controllers read whole 32-bit words (GVCP READMEM counts are multiples of 4), so the last
    // word may reach up to 3 bytes past the XML: serve those as zeros.
    xml_.assign(xml, xml + size);
    xml_.resize((size + 3) / 4 * 4, 0);
  }
  std::array<char, 513> url{};
  arv_fake_camera_read_memory(camera_, kRegXmlUrl0, 512, url.data());
  xml_address_ = xmlAddressFromUrl(url.data());
  default_heartbeat_ms_ = std::max(arv_fake_camera_get_heartbeat_timeout(camera_), kMinHeartbeatTimeoutMs);
  if (xml_address_ < ARV_FAKE_CAMERA_MEMORY_SIZE) xml_address_ = ARV_FAKE_CAMERA_MEMORY_SIZE;
}

std::vector<std::uint8_t> Responder::handle(std::span<const std::uint8_t> request, const Peer& from,
                                            Channel channel, std::int64_t now_ms) {
  expireController(now_ms);
  // Not a GVCP command (too short for a header, or not the command key): not ours to answer.
  if (request.size() < kHeaderSize || request[0] != kCommandKey) return {};
  const std::uint8_t flags = request[1];
  const std::uint16_t command = readBe16(request, 2);
  const std::uint16_t length = readBe16(request, 4);
  const std::uint16_t request_id = readBe16(request, 6);
  // The broadcast socket serves discovery and nothing else; resend requests are never answered
  // (and a virtual camera has nothing to resend).
  if (channel == Channel::Discovery && command != DISCOVERY_CMD) return {};
  if (command == PACKETRESEND_CMD) return {};
  if (isController(from)) last_heartbeat_ms_ = now_ms;

  Reply reply;
  // An acknowledge code is the command code plus one; for codes we do not know, the same rule.
  reply.answer = static_cast<std::uint16_t>(command | 0x0001);
  if (length > request.size() - kHeaderSize) {
    reply.status = GEV_STATUS_INVALID_HEADER;  // declares more payload than the datagram holds
  } else {
    const std::span<const std::uint8_t> payload = request.subspan(kHeaderSize, length);
    switch (command) {
      case DISCOVERY_CMD:
        reply.answer = DISCOVERY_ACK;
        reply.payload.resize(kDiscoveryDataSize);
        reply.status = readBytes(0, kDiscoveryDataSize, reply.payload.data());
        if (reply.status != GEV_STATUS_SUCCESS) reply.payload.clear();
        break;
      case READREG_CMD: readRegisters(payload, reply); break;
      case WRITEREG_CMD: writeRegisters(payload, from, now_ms, reply); break;
      case READMEM_CMD: readMemory(payload, reply); break;
      case WRITEMEM_CMD: writeMemory(payload, from, reply); break;
      default: reply.status = GEV_STATUS_NOT_IMPLEMENTED; break;  // FORCEIP, ACTION, EVENT, ...
    }
  }
  // Discovery is always answered; everything else only when the sender asked for it.
  if (command != DISCOVERY_CMD && (flags & kFlagAcknowledge) == 0) return {};
  std::vector<std::uint8_t> out(kHeaderSize + reply.payload.size());
  writeBe16(out, 0, reply.status);
  writeBe16(out, 2, reply.answer);
  writeBe16(out, 4, static_cast<std::uint16_t>(reply.payload.size()));
  writeBe16(out, 6, request_id);
  std::copy(reply.payload.begin(), reply.payload.end(), out.begin() + kHeaderSize);
  return out;
}

// READREG: a list of 32-bit addresses; the acknowledge carries the values read before any failure.
void Responder::readRegisters(std::span<const std::uint8_t> payload, Reply& reply) {
  if (payload.empty() || payload.size() % 4 != 0 || payload.size() > kMaxPayload) {
    reply.status = GEV_STATUS_INVALID_PARAMETER;
    return;
  }
  for (std::size_t at = 0; at < payload.size(); at += 4) {
    const std::uint32_t address = readBe32(payload, at);
    if (address % 4 != 0) {
      reply.status = GEV_STATUS_BAD_ALIGNMENT;
      return;
    }
    std::array<std::uint8_t, 4> value{};
    reply.status = readBytes(address, 4, value.data());
    if (reply.status != GEV_STATUS_SUCCESS) return;
    reply.payload.insert(reply.payload.end(), value.begin(), value.end());
  }
}

// WRITEREG: (address, value) pairs, written in order up to the first failure. The acknowledge's
// index is the number of registers written.
void Responder::writeRegisters(std::span<const std::uint8_t> payload, const Peer& from, std::int64_t now_ms,
                               Reply& reply) {
  if (payload.empty() || payload.size() % 8 != 0 || payload.size() > kMaxPayload) {
    reply.status = GEV_STATUS_INVALID_PARAMETER;
  } else {
    std::uint16_t written = 0;
    for (std::size_t at = 0; at < payload.size(); at += 8, ++written) {
      reply.status = writeRegister(readBe32(payload, at), readBe32(payload, at + 4), from, now_ms);
      if (reply.status != GEV_STATUS_SUCCESS) break;
    }
    reply.payload.assign(4, 0);
    writeBe16(reply.payload, 2, written);
  }
}

// READMEM: address(32) reserved(16) count(16); the acknowledge echoes the address, then the data.
void Responder::readMemory(std::span<const std::uint8_t> payload, Reply& reply) {
  if (payload.size() != 8) {
    reply.status = GEV_STATUS_INVALID_PARAMETER;
    return;
  }
  const std::uint32_t address = readBe32(payload, 0);
  const std::uint16_t count = readBe16(payload, 6);
  reply.payload.assign(payload.begin(), payload.begin() + 4);
  if (count == 0 || count > kMaxMemoryBlock) {
    reply.status = GEV_STATUS_INVALID_PARAMETER;
  } else if (address % 4 != 0 || count % 4 != 0) {
    reply.status = GEV_STATUS_BAD_ALIGNMENT;
  } else {
    reply.payload.resize(4 + count);
    reply.status = readBytes(address, count, reply.payload.data() + 4);
    if (reply.status != GEV_STATUS_SUCCESS) reply.payload.resize(4);
  }
}

// WRITEMEM: address(32) then the data. Checked as a whole, then written word by word through the
// same rules as WRITEREG (so CCP and the heartbeat timeout keep their meaning). The acknowledge's
// index is the number of bytes written.
void Responder::writeMemory(std::span<const std::uint8_t> payload, const Peer& from, Reply& reply) {
  reply.payload.assign(4, 0);
  if (payload.size() < 8 || payload.size() - 4 > kMaxMemoryBlock) {
    reply.status = GEV_STATUS_INVALID_PARAMETER;
    return;
  }
  const std::uint32_t address = readBe32(payload, 0);
  const std::size_t count = payload.size() - 4;
  if (address % 4 != 0 || count % 4 != 0) {
    reply.status = GEV_STATUS_BAD_ALIGNMENT;
    return;
  }
  reply.status = writableRange(address, count);
  if (reply.status == GEV_STATUS_SUCCESS && !isController(from)) reply.status = GEV_STATUS_ACCESS_DENIED;
  if (reply.status != GEV_STATUS_SUCCESS) return;
  std::uint16_t written = 0;
  for (std::size_t at = 0; at < count; at += 4) {
    // The heartbeat was refreshed by this very command: the time only matters for CCP.
    reply.status = writeRegister(static_cast<std::uint32_t>(address + at), readBe32(payload, 4 + at), from,
                                 last_heartbeat_ms_);
    if (reply.status != GEV_STATUS_SUCCESS) break;
    written = static_cast<std::uint16_t>(written + 4);
  }
  writeBe16(reply.payload, 2, written);
}

std::uint16_t Responder::readBytes(std::uint64_t address, std::uint32_t count, std::uint8_t* out) {
  const std::uint64_t end = address + count;  // 64-bit: no wrap-around for addresses near 2^32
  if (end <= kRegisterSpaceEnd) {
    return arv_fake_camera_read_memory(camera_, static_cast<guint32>(address), count, out)
               ? GEV_STATUS_SUCCESS
               : GEV_STATUS_INVALID_ADDRESS;
  }
  if (address >= xml_address_ && end <= xml_address_ + xml_.size()) {
    std::memcpy(out, xml_.data() + (address - xml_address_), count);
    return GEV_STATUS_SUCCESS;
  }
  return GEV_STATUS_INVALID_ADDRESS;
}

std::uint16_t Responder::writableRange(std::uint64_t address, std::uint64_t count) const {
  const std::uint64_t end = address + count;
  if (end > kRegisterSpaceEnd) {
    const bool in_xml = address >= xml_address_ && end <= xml_address_ + xml_.size();
    return in_xml ? GEV_STATUS_WRITE_PROTECT : GEV_STATUS_INVALID_ADDRESS;
  }
  for (const Range& r : kReadOnly) {
    if (address < r.end && end > r.begin) return GEV_STATUS_WRITE_PROTECT;
  }
  return GEV_STATUS_SUCCESS;
}

std::uint16_t Responder::writeRegister(std::uint32_t address, std::uint32_t value, const Peer& from,
                                       std::int64_t now_ms) {
  if (address % 4 != 0) return GEV_STATUS_BAD_ALIGNMENT;
  if (address == kRegControlChannelPrivilege) {
    // One controller at a time; switchover (taking control from a living controller) is not
    // offered, so anyone else is refused until the controller releases or its heartbeat runs out.
    if (controller_ && !isController(from)) return GEV_STATUS_ACCESS_DENIED;
    const std::uint32_t wanted = value & (kCcpControl | kCcpExclusive);
    if (wanted == 0) {
      if (controller_) releaseControl();
      return GEV_STATUS_SUCCESS;
    }
    controller_ = from;
    last_heartbeat_ms_ = now_ms;
    arv_fake_camera_set_control_channel_privilege(camera_, wanted);
    return GEV_STATUS_SUCCESS;
  }
  if (const std::uint16_t status = writableRange(address, 4); status != GEV_STATUS_SUCCESS) return status;
  if (!isController(from)) return GEV_STATUS_ACCESS_DENIED;
  if (address == kRegHeartbeatTimeout) value = std::max(value, kMinHeartbeatTimeoutMs);
  if (address == kRegTimestampControl) {
    // Latch: the counter's value now, readable at 0x0948. The counter is the clock the frames are
    // stamped with; it runs on, so a reset is acknowledged and changes nothing.
    if ((value & kTimestampLatch) != 0) {
      const std::uint64_t now = deviceTimeNs();
      arv_fake_camera_write_register(camera_, kRegTimestampValueHigh, static_cast<std::uint32_t>(now >> 32));
      arv_fake_camera_write_register(camera_, kRegTimestampValueLow, static_cast<std::uint32_t>(now));
    }
    return GEV_STATUS_SUCCESS;
  }
  if (address == ARV_FAKE_CAMERA_REGISTER_TRIGGER_SOFTWARE && triggers_.size() < kMaxQueuedTriggers) {
    // The exposure starts now: the frame carries this instant, however long it takes to make.
    triggers_.push_back(Trigger{deviceTimeNs(), std::chrono::steady_clock::now()});
  }
  return arv_fake_camera_write_register(camera_, address, value) ? GEV_STATUS_SUCCESS : GEV_STATUS_INVALID_ADDRESS;
}

std::optional<Responder::Trigger> Responder::takeTrigger() {
  if (triggers_.empty()) return std::nullopt;
  const Trigger first = triggers_.front();
  triggers_.pop_front();
  return first;
}

bool Responder::expireController(std::int64_t now_ms) {
  if (!controller_) return false;
  const std::uint32_t timeout = std::max(arv_fake_camera_get_heartbeat_timeout(camera_), kMinHeartbeatTimeoutMs);
  if (now_ms - last_heartbeat_ms_ <= static_cast<std::int64_t>(timeout)) return false;
  releaseControl();
  return true;
}

// Without a controller there is nobody to stream to: stop acquisition and close the stream channel,
// so that the next controller starts from a quiet camera with the default heartbeat.
void Responder::releaseControl() {
  controller_.reset();
  triggers_.clear();
  // The heartbeat timeout belongs to the session that set it.
  arv_fake_camera_write_register(camera_, kRegHeartbeatTimeout, default_heartbeat_ms_);
  arv_fake_camera_set_control_channel_privilege(camera_, 0);
  arv_fake_camera_write_register(camera_, kRegAcquisition, 0);
  arv_fake_camera_write_register(camera_, kRegStreamHostPort, 0);
}

}  // namespace stampscan::sim::gvcp
