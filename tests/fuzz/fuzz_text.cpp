// Fuzz target for the text cloud reader: parseTextCloud on arbitrary bytes.
#include "fuzz_targets.hpp"

#include "stampscan/fitting/text_io.hpp"

#include <stdexcept>
#include <string>

namespace stampscan::fuzz {

namespace {
// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}
}  // namespace

int fuzzText(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    fitting::ReadReport report;
    const fitting::Cloud cloud = fitting::parseTextCloud(text, "fuzz.csv", &report);
    cloud.validate();  // every attribute aligned with the positions
    require(!cloud.empty(), "parseTextCloud returned no points");
    require(report.points_read == cloud.size(), "report.points_read differs from the cloud size");
    require(!cloud.hasColors(), "text clouds have no colours");
    for (const fitting::Vec3& p : cloud.positions) require(p.allFinite(), "non-finite point kept");
  } catch (const fitting::InputError& e) {
    require(std::string(e.what()).rfind("fuzz.csv: ", 0) == 0, "InputError message does not start with the file");
    require(!e.reason().empty(), "InputError without a reason");
  }
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzText(data, size);
}
#endif
