// The I++ DME error list (spec §8.2) with its default severity classes (§8.1), shared by the driver
// (to name an error it receives) and the virtual CMM (to send the right number, class and text).
#pragma once

#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <string>
#include <string_view>

namespace stampscan::drivers::cmm::ipp {

// The numbers StampScan's driver and virtual CMM use by name; the table in ipp_errors.cpp has all.
namespace error {
inline constexpr int kIllegalTag = 1;
inline constexpr int kNoSpaceAtPos6 = 2;
inline constexpr int kTransactionAborted = 6;
inline constexpr int kIllegalCharacter = 7;
inline constexpr int kProtocolError = 8;
inline constexpr int kUnsupportedCommand = 501;
inline constexpr int kIncorrectArguments = 502;
inline constexpr int kArgumentOutOfRange = 504;
inline constexpr int kArgumentNotRecognized = 505;
inline constexpr int kArgumentNotSupported = 506;
inline constexpr int kBadContext = 508;
inline constexpr int kBadArgument = 509;
inline constexpr int kBadProperty = 510;
inline constexpr int kErrorProcessingMethod = 511;
inline constexpr int kNoDaemonsActive = 512;
inline constexpr int kDaemonDoesNotExist = 513;
inline constexpr int kUseClearAllErrors = 514;
inline constexpr int kDaemonAlreadyExists = 515;
inline constexpr int kUnableToMove = 1011;
inline constexpr int kToolNotFound = 1502;
inline constexpr int kToolNotDefined = 1503;
inline constexpr int kMachineLimit = 2500;
inline constexpr int kAngleOutOfRange = 2505;
}  // namespace error

struct ErrorDefinition {
  int number;
  int severity;  // default class of §8.2
  std::string_view text;
};

// The §8.2 entry for `number`, or nullptr for numbers the list does not define.
const ErrorDefinition* findError(int number);

// An error response for `number` with the §8.2 class and text (class 3, "Unknown error" for numbers
// the list does not define) raised by `method`.
ErrorReport makeError(int number, std::string method);

// §8.1: only errors of class 2 and above put the server into the error state that needs
// ClearAllErrors(); classes 0 and 1 are information and warnings.
inline bool needsClearAllErrors(int severity) { return severity >= 2; }

// "I++ DME error 2500 (class 3) in GoTo: Machine limit encountered [Move Out Of Limits]"
std::string describe(const ErrorReport& error);

}  // namespace stampscan::drivers::cmm::ipp
