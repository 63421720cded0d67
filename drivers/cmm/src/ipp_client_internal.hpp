// What ipp_client.cpp and ipp_client_motion.cpp share: one request to the CMM, its result, and
// readers for the data of `#` responses.
#pragma once

#include "ipp_channel.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::drivers::cmm {

struct IppCmm::Request {
  std::string name{};
  std::vector<ipp::Argument> args{};
  bool event = false;         // an E tag: the server's fast queue (§4, §6.2.1)
  bool moves = false;         // bounded by motion_timeout rather than reply_timeout
  bool during_abort = false;  // sent by abort() itself, so not held back until abort() is done
  detail::IppChannel::LineHandler daemon{};  // `#` lines of the event tag (OnMoveReportE)
};

struct IppCmm::Result {
  ipp::Tag tag;
  std::string line;  // the command as sent
  std::vector<std::vector<ipp::Argument>> data;
  std::vector<ipp::ErrorReport> errors;    // class 2 and above (§8.1)
  std::vector<ipp::ErrorReport> warnings;  // class 0 and 1
  bool aborted = false;                    // ended by our own AbortE
  std::uint64_t aborts_before = 0;         // abort() calls begun before it was sent
};

namespace detail {

// The first item of `items` that is the call `name`, or nullptr.
inline const ipp::Argument* findCall(const std::vector<ipp::Argument>& items, std::string_view name) {
  for (const ipp::Argument& a : items) {
    if (a.isCall(name)) return &a;
  }
  return nullptr;
}

// The value of `Name(number)` in `items`, e.g. X(12.5) or Tool.GoToPar.Speed(100).
inline std::optional<double> numberOf(const std::vector<ipp::Argument>& items, std::string_view name) {
  const ipp::Argument* call = findCall(items, name);
  if (call == nullptr || call->args.size() != 1 || call->args[0].kind != ipp::Argument::Kind::Number) {
    return std::nullopt;
  }
  return call->args[0].number;
}

}  // namespace detail
}  // namespace stampscan::drivers::cmm
