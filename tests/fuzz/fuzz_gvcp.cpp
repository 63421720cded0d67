// Fuzz target for the virtual cameras' GVCP server: a sequence of request datagrams through
// gvcp::Responder over a fresh Aravis camera model, as they would arrive on UDP 3956.
//
// Input framing, repeated: one control byte, a big-endian 16-bit length, then that many bytes of
// datagram (fewer at the end of the input). Control bits 0-1 pick the sender (0 and 1: two
// applications on loopback, 2: the first one through the broadcast discovery socket); bits 2-7 are
// the time since the previous datagram in 100 ms steps, so heartbeats can run out.
#include "fuzz_targets.hpp"

#include "gvcp_protocol.hpp"
#include "gvcp_responder.hpp"

#include <arv.h>

#include <algorithm>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

namespace stampscan::fuzz {

namespace {
// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}

bool knownStatus(std::uint16_t status) {
  using namespace sim::gvcp;
  switch (status) {
    case GEV_STATUS_SUCCESS: case GEV_STATUS_NOT_IMPLEMENTED: case GEV_STATUS_INVALID_PARAMETER:
    case GEV_STATUS_INVALID_ADDRESS: case GEV_STATUS_WRITE_PROTECT: case GEV_STATUS_BAD_ALIGNMENT:
    case GEV_STATUS_ACCESS_DENIED: case GEV_STATUS_INVALID_HEADER:
      return true;
    default:
      return false;
  }
}

struct Unref {
  void operator()(ArvFakeCamera* camera) const { g_object_unref(camera); }
};
}  // namespace

int fuzzGvcp(const std::uint8_t* data, std::size_t size) {
  namespace gvcp = sim::gvcp;
  const std::unique_ptr<ArvFakeCamera, Unref> camera(arv_fake_camera_new_full("FUZZ", nullptr));
  require(camera != nullptr, "Aravis cannot create a fake camera");
  gvcp::Responder responder(camera.get());
  const gvcp::Peer peers[2] = {{0x7F000001, 40000}, {0x7F000001, 40001}};
  const std::span<const std::uint8_t> input(data, size);
  std::int64_t now_ms = 1'000'000;
  for (std::size_t at = 0; at + 3 <= input.size();) {
    const std::uint8_t control = input[at];
    const std::size_t length = std::min<std::size_t>(gvcp::readBe16(input, at + 1), input.size() - at - 3);
    const std::span<const std::uint8_t> request = input.subspan(at + 3, length);
    at += 3 + length;
    now_ms += 100 * (control >> 2);
    const int sender = control & 0x3;
    const gvcp::Channel channel = sender == 2 ? gvcp::Channel::Discovery : gvcp::Channel::Unicast;
    const std::vector<std::uint8_t> reply = responder.handle(request, peers[sender == 1 ? 1 : 0], channel, now_ms);
    if (reply.empty()) continue;
    // Whatever came in, an acknowledge is well formed: a GVCP header that matches the request,
    // a known status, a length that is the payload's, and no more than a GVCP datagram can carry.
    require(request.size() >= gvcp::kHeaderSize && request[0] == gvcp::kCommandKey, "answered a non-command");
    require(reply.size() >= gvcp::kHeaderSize && reply.size() <= gvcp::kHeaderSize + gvcp::kMaxPayload, "reply size out of range");
    require(knownStatus(gvcp::readBe16(reply, 0)), "unknown status code");
    require(gvcp::readBe16(reply, 4) == reply.size() - gvcp::kHeaderSize, "reply length field is wrong");
    require(gvcp::readBe16(reply, 6) == gvcp::readBe16(request, 6), "ack id differs from the request id");
    const std::uint16_t command = gvcp::readBe16(request, 2);
    require(gvcp::readBe16(reply, 2) == (command | 0x0001), "acknowledge code does not match the command");
    require(channel == gvcp::Channel::Unicast || command == gvcp::DISCOVERY_CMD, "discovery socket served a non-discovery");
  }
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzGvcp(data, size);
}
#endif
