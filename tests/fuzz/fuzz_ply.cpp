// Fuzz target for the PLY reader: parsePly on arbitrary bytes.
#include "fuzz_targets.hpp"

#include "stampscan/fitting/ply_io.hpp"

#include <stdexcept>
#include <string>

namespace stampscan::fuzz {

namespace {
// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}
}  // namespace

int fuzzPly(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    fitting::ReadReport report;
    const fitting::Mesh mesh = fitting::parsePly(bytes, "fuzz.ply", &report);
    const fitting::Cloud& cloud = mesh.vertices;
    cloud.validate();  // every attribute aligned with the positions
    require(!cloud.empty(), "parsePly returned no points");
    require(report.points_read == cloud.size(), "report.points_read differs from the cloud size");
    require(report.faces_read == mesh.triangles.size(), "report.faces_read differs from the triangle count");
    for (const fitting::Vec3& p : cloud.positions) require(p.allFinite(), "non-finite point kept");
    for (const fitting::Triangle& t : mesh.triangles) {
      for (const std::uint32_t v : t.v) require(v < cloud.size(), "triangle index out of range");
    }
  } catch (const fitting::InputError& e) {
    require(std::string(e.what()).rfind("fuzz.ply: ", 0) == 0, "InputError message does not start with the file");
    require(!e.reason().empty(), "InputError without a reason");
  }
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzPly(data, size);
}
#endif
