#include "stampscan/drivers/cmm/ipp_errors.hpp"

#include <algorithm>
#include <array>
#include <iomanip>
#include <sstream>

namespace stampscan::drivers::cmm::ipp {

namespace {
// §8.2, in the order of the spec. Text exactly as listed there (§8.1: the Text field "must be the
// text string shown in section 8.2").
constexpr std::array<ErrorDefinition, 52> kErrors{{
    {0, 0, "Buffer full"},
    {1, 2, "Illegal tag"},
    {2, 2, "No space at pos. 6"},
    {3, 2, "Reserved"},
    {4, 2, "Reserved"},
    {5, 2, "Reserved"},
    {6, 2, "Transaction aborted (Use ClearAllErrors To Continue)"},
    {7, 3, "Illegal character"},
    {8, 3, "Protocol error"},
    {500, 3, "Emergency stop"},
    {501, 3, "Unsupported command"},
    {502, 3, "Incorrect arguments"},
    {503, 9, "Controller communications failure"},
    {504, 1, "Argument out of range"},
    {505, 3, "Argument not recognized"},
    {506, 3, "Argument not supported"},
    {507, 3, "Illegal command"},
    {508, 3, "Bad context"},
    {509, 3, "Bad argument"},
    {510, 3, "Bad property"},
    {511, 3, "Error processing method"},
    {512, 1, "No daemons are active"},
    {513, 2, "Daemon does not exist"},
    {514, 2, "Use ClearAllErrors to continue"},
    {515, 2, "Daemon already exists"},
    {1000, 3, "Machine in error state"},
    {1001, 2, "Illegal touch"},
    {1002, 9, "Axis does not exist"},
    {1003, 2, "No touch"},
    {1004, 9, "Number of angles not supported on current device"},
    {1005, 3, "Error during home"},
    {1006, 2, "Surface not found"},
    {1007, 3, "Theta out of range"},
    {1008, 3, "Target position out of machine volume"},
    {1009, 3, "Air pressure out of range"},
    {1010, 2, "Vector has no norm"},
    {1011, 2, "Unable to move"},
    {1012, 2, "Bad lock combinations"},
    {1500, 3, "Failed to re-seat head"},
    {1501, 3, "Probe not armed"},
    {1502, 3, "Tool not found"},
    {1503, 3, "Tool not defined"},
    {2000, 3, "Tool not calibrated"},
    {2001, 2, "Head error excessive force"},
    {2002, 3, "Type of probe does not allow this operation"},
    {2500, 3, "Machine limit encountered [Move Out Of Limits]"},
    {2501, 3, "Axis not active"},
    {2502, 3, "Axis position error"},
    {2503, 9, "Scale read head failure"},
    {2504, 3, "Collision"},
    {2505, 2, "Specified angle out of range"},
    {2506, 2, "Part not aligned"},
}};
}  // namespace

const ErrorDefinition* findError(int number) {
  const auto it = std::find_if(kErrors.begin(), kErrors.end(),
                               [number](const ErrorDefinition& e) { return e.number == number; });
  return it == kErrors.end() ? nullptr : &*it;
}

ErrorReport makeError(int number, std::string method) {
  const ErrorDefinition* definition = findError(number);
  if (definition == nullptr) return {3, number, std::move(method), "Unknown error"};
  return {definition->severity, number, std::move(method), std::string(definition->text)};
}

std::string describe(const ErrorReport& error) {
  std::ostringstream out;
  out << "I++ DME error " << std::setw(4) << std::setfill('0') << error.number << " (class " << error.severity
      << ")";
  if (!error.method.empty()) out << " in " << error.method;
  out << ": " << error.text;
  return out.str();
}

}  // namespace stampscan::drivers::cmm::ipp
