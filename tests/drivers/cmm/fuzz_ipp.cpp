// Fuzz target for the I++ DME codec: the bytes are framed into lines as the driver and the virtual
// CMM frame them, and every line goes through parseCommand, parseReply and parseArguments.
#include "fuzz_ipp.hpp"

#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <stdexcept>
#include <string>
#include <string_view>

namespace stampscan::fuzz {

namespace {
namespace ipp = drivers::cmm::ipp;

// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}

void checkError(const ipp::ProtocolError& e, std::string_view line) {
  const int n = e.errorNumber();
  require(n == 1 || n == 2 || n == 7 || n == 8, "ProtocolError with a number outside 0001, 0002, 0007, 0008");
  require(e.column() >= 1 && e.column() <= line.size() + 1, "ProtocolError column outside the line");
  require(!e.reason().empty(), "ProtocolError without a reason");
  require(std::string_view(e.what()).rfind("column ", 0) == 0, "ProtocolError message does not start with the column");
}

void fuzzLine(std::string_view line) {
  try {
    const ipp::Command command = ipp::parseCommand(line);
    require(!command.tag.isServerEvent(), "a command was accepted on E0000");
    require(ipp::parseCommand(ipp::formatCommand(command)) == command, "command does not survive format and parse");
  } catch (const ipp::ProtocolError& e) {
    checkError(e, line);
  }
  try {
    const ipp::Reply reply = ipp::parseReply(line);
    require(ipp::parseReply(ipp::formatReply(reply)) == reply, "reply does not survive format and parse");
  } catch (const ipp::ProtocolError& e) {
    checkError(e, line);
  }
  try {
    const std::vector<ipp::Argument> args = ipp::parseArguments(line);
    require(!args.empty(), "parseArguments returned nothing");
    require(ipp::parseArguments(ipp::formatArguments(args)) == args, "arguments do not survive format and parse");
  } catch (const ipp::ProtocolError& e) {
    checkError(e, line);
  }
}
}  // namespace

int fuzzIpp(const std::uint8_t* data, std::size_t size) {
  ipp::LineFramer framer(4096);  // a small limit, so that the over-long path is reached too
  framer.append(std::string_view(reinterpret_cast<const char*>(data), size));
  while (std::optional<ipp::LineFramer::Line> line = framer.next()) {
    require(line->text.size() <= 4096, "framed line longer than the limit");
    fuzzLine(line->text);
  }
  // What never saw its CR LF is a line too, for the parsers' sake.
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  fuzzLine(all.substr(0, all.find('\n')));
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzIpp(data, size);
}
#endif
