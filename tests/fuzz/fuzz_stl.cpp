// Fuzz target for the STL reader: parseStl on arbitrary bytes (binary or ASCII, told apart by size).
#include "fuzz_targets.hpp"

#include "stampscan/acquisition/nominal_model.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace stampscan::fuzz {

namespace {
// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}
}  // namespace

int fuzzStl(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    const acquisition::NominalModel model = acquisition::parseStl(bytes, "fuzz.stl");
    require(!model.triangles.empty(), "parseStl returned no triangles");
    require(model.source == "fuzz.stl", "the model does not name its source");
    require(model.vertices.size() <= 3 * model.triangles.size(), "more vertices than the triangles' corners");
    for (const auto& v : model.vertices)
      for (const double c : v) require(std::isfinite(c), "non-finite coordinate kept");
    for (const auto& t : model.triangles)
      for (const std::uint32_t i : t) require(i < model.vertices.size(), "triangle index out of range");
    require(std::isfinite(model.area()), "non-finite area");
  } catch (const acquisition::ModelError& e) {
    const std::string message = e.what();
    require(message.rfind("fuzz.stl", 0) == 0, "ModelError message does not start with the file");
    require(message.find('\n') == std::string::npos, "ModelError message is not one line");
  }
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzStl(data, size);
}
#endif
