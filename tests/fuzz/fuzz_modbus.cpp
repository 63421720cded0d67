// Fuzz target for the virtual PLC's request handling: the bytes of a client's stream are framed at
// their MBAP lengths (all at once and in small pieces, which must agree), each ADU gets its verdict,
// and every ADU let through is answered by libmodbus's modbus_reply() over a socket pair, exactly
// as the server does. libmodbus trusts its input to be framed consistently: a frame the verdict lets
// through that makes it read outside the frame is a bug the sanitizers catch here.
#include "fuzz_targets.hpp"

#include "modbus_frame.hpp"
#include "stampscan/drivers/plc/plc_register_map.hpp"

#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

#include <modbus.h>

namespace stampscan::fuzz {

namespace {
namespace plc = drivers::plc;
namespace detail = sim::detail;
using Adus = std::vector<std::vector<std::uint8_t>>;

// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}

Adus frame(std::span<const std::uint8_t> bytes, std::size_t piece) {
  detail::ModbusTcpFramer framer;
  Adus adus;
  for (std::size_t at = 0; at < bytes.size() && !framer.broken(); at += piece) {
    framer.append(bytes.subspan(at, std::min(piece, bytes.size() - at)));
    while (std::optional<std::vector<std::uint8_t>> adu = framer.next()) adus.push_back(std::move(*adu));
  }
  return adus;
}

// libmodbus answering one ADU on a socket pair; the reply as the client would read it.
std::vector<std::uint8_t> replyOf(const std::vector<std::uint8_t>& adu, modbus_mapping_t& image) {
  std::array<int, 2> pair{};
  require(::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, pair.data()) == 0, "no socket pair");
  modbus_t* context = modbus_new_tcp("127.0.0.1", 1502);
  modbus_set_socket(context, pair[0]);
  modbus_set_response_timeout(context, 0, 1);  // as the server: no sleep before exception replies
  const int sent = modbus_reply(context, adu.data(), static_cast<int>(adu.size()), &image);
  modbus_free(context);
  std::vector<std::uint8_t> reply(MODBUS_TCP_MAX_ADU_LENGTH + 1);
  const ssize_t n = sent > 0 ? ::recv(pair[1], reply.data(), reply.size(), MSG_DONTWAIT) : 0;
  ::close(pair[0]);
  ::close(pair[1]);
  reply.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
  return reply;
}
}  // namespace

int fuzzModbus(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  const Adus whole = frame(bytes, std::max<std::size_t>(size, 1));
  require(frame(bytes, 3) == whole, "framing depends on how the stream is cut");
  const std::unique_ptr<modbus_mapping_t, void (*)(modbus_mapping_t*)> image(
      modbus_mapping_new_start_address(0, plc::kCoilCount, 0, plc::kDiscreteInputCount, 0, plc::kHoldingRegisterCount,
                                       0, plc::kInputRegisterCount),
      &modbus_mapping_free);
  require(image != nullptr, "no register image");
  for (const std::vector<std::uint8_t>& adu : whole) {
    require(adu.size() >= detail::kMbapHeaderLength + 1 && adu.size() <= detail::kMaxAduLength, "an ADU of impossible size");
    const detail::RequestVerdict verdict = detail::checkRequest(adu, 1);
    if (verdict.action == detail::RequestAction::Refuse) {
      const std::vector<std::uint8_t> reply = detail::exceptionResponse(adu, verdict.exception_code);
      require(reply.size() == 9 && (reply[7] & 0x80) != 0 && reply[8] == verdict.exception_code, "a bad exception response");
      require(!verdict.reason.empty(), "a refusal without a reason");
    } else if (verdict.action == detail::RequestAction::Serve) {
      const std::vector<std::uint8_t> reply = replyOf(adu, *image);
      require(reply.size() >= 9, "libmodbus did not answer a served request");
      require(reply[0] == adu[0] && reply[1] == adu[1], "the reply has another transaction id");
      require(static_cast<std::size_t>((reply[4] << 8) | reply[5]) + 6 == reply.size(), "the reply's MBAP length is wrong");
      require((reply[7] & 0x7F) == adu[7], "the reply answers another function");
    }
  }
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzModbus(data, size);
}
#endif
