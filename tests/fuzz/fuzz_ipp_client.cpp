// Fuzz target for I++ DME lines at the client: a server's bytes, framed at the full line limit and
// parsed as responses the way the CMM driver reads them, including the driver's readers for `#` data.
#include "fuzz_targets.hpp"

#include "ipp_client_internal.hpp"
#include "stampscan/drivers/cmm/ipp_errors.hpp"
#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <optional>
#include <stdexcept>
#include <string_view>

namespace stampscan::fuzz {

namespace {
namespace ipp = drivers::cmm::ipp;

// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}
}  // namespace

int fuzzIppClient(const std::uint8_t* data, std::size_t size) {
  ipp::LineFramer framer;  // the driver's limit
  framer.append(std::string_view(reinterpret_cast<const char*>(data), size));
  while (std::optional<ipp::LineFramer::Line> line = framer.next()) {
    require(line->text.size() <= ipp::kMaxLineLength, "framed line longer than the limit");
    try {
      const ipp::Reply reply = ipp::parseReply(line->text);
      require(ipp::parseReply(ipp::formatReply(reply)) == reply, "a response does not survive format and parse");
      if (reply.kind == ipp::ReplyKind::Error) {
        require(!ipp::describe(reply.error).empty(), "an error without a description");
      }
      for (const ipp::Argument& item : reply.data) {
        if (item.kind != ipp::Argument::Kind::Call) continue;
        // The driver's readers must agree with each other on every item.
        const ipp::Argument* found = drivers::cmm::detail::findCall(reply.data, item.text);
        require(found != nullptr, "findCall misses an item that is there");
        const std::optional<double> number = drivers::cmm::detail::numberOf(reply.data, item.text);
        require(number.has_value() == (found->args.size() == 1 && found->args[0].kind == ipp::Argument::Kind::Number),
                "numberOf disagrees with the item");
      }
    } catch (const ipp::ProtocolError& e) {
      require(e.column() >= 1 && e.column() <= line->text.size() + 1, "ProtocolError column outside the line");
    }
  }
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzIppClient(data, size);
}
#endif
