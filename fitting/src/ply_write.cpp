// Writing PLY clouds and meshes, ASCII or binary little-endian, atomically: the data goes to a
// temporary file beside the destination, which replaces the destination only once complete.
#include "stampscan/fitting/ply_io.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string_view>
#include <system_error>
#include <vector>

namespace stampscan::fitting {

namespace {

namespace fs = std::filesystem;

// The names the reader maps to dedicated attributes; a scalar of the same name would be misread.
constexpr std::array<std::string_view, 10> kReservedNames{"x",  "y",      "z",   "nx",    "ny",
                                                          "nz", "strain", "red", "green", "blue"};

std::runtime_error writeError(const fs::path& file, const std::string& reason) {
  return std::runtime_error("cannot write " + file.string() + ": " + reason);
}

void checkScalarName(const fs::path& file, const std::string& name) {
  const bool printable = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u > 0x20 && u < 0x7f;
  });
  if (!printable) {
    throw std::invalid_argument("cannot write " + file.string() + ": scalar name '" + name +
                                "' is not a PLY property name (empty, or has spaces or control characters)");
  }
  if (std::find(kReservedNames.begin(), kReservedNames.end(), name) != kReservedNames.end()) {
    throw std::invalid_argument("cannot write " + file.string() + ": scalar name '" + name +
                                "' clashes with a built-in vertex property");
  }
}

void checkTriangles(const fs::path& file, std::size_t n, const std::vector<Triangle>& triangles) {
  // Face indices are written as PLY `int`.
  if (!triangles.empty() && n > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw std::invalid_argument("cannot write " + file.string() + ": too many vertices for int face indices");
  }
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (const std::uint32_t v : triangles[i].v) {
      if (v >= n) {
        throw std::invalid_argument("cannot write " + file.string() + ": triangle " + std::to_string(i) +
                                    " has vertex index " + std::to_string(v) + " but the mesh has " +
                                    std::to_string(n) + " vertices");
      }
    }
  }
}

std::string buildHeader(const Cloud& cloud, const std::vector<Triangle>& triangles, const PlyWriteOptions& options) {
  const std::string real = options.precision == PlyPrecision::Double ? "double" : "float";
  std::string header = "ply\n";
  header += options.format == PlyFormat::Ascii ? "format ascii 1.0\n" : "format binary_little_endian 1.0\n";
  if (!options.comment.empty()) {
    std::string comment = options.comment;
    std::replace_if(comment.begin(), comment.end(), [](char c) { return c == '\n' || c == '\r'; }, ' ');
    header += "comment " + comment + "\n";
  }
  header += "element vertex " + std::to_string(cloud.size()) + "\n";
  for (const char* axis : {"x", "y", "z"}) header += "property " + real + " " + axis + "\n";
  if (cloud.hasNormals()) {
    for (const char* axis : {"nx", "ny", "nz"}) header += "property " + real + " " + axis + "\n";
  }
  if (cloud.hasStrain()) header += "property " + real + " strain\n";
  for (const auto& entry : cloud.scalars) header += "property " + real + " " + entry.first + "\n";
  if (cloud.hasColors()) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (!triangles.empty()) {
    header += "element face " + std::to_string(triangles.size()) + "\n";
    header += "property list uchar int vertex_indices\n";
  }
  header += "end_header\n";
  return header;
}

// Narrows to float; values beyond float's range become infinite (a plain cast would be undefined).
float toFloat(double value) {
  if (std::isfinite(value) && std::abs(value) > std::numeric_limits<float>::max()) {
    return value > 0 ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
  }
  return static_cast<float>(value);
}

// Encodes values into a buffer that is handed to the stream in large pieces.
class Encoder {
 public:
  Encoder(std::ofstream& out, const PlyWriteOptions& options)
      : out_(out), ascii_(options.format == PlyFormat::Ascii), doubles_(options.precision == PlyPrecision::Double) {
    buffer_.reserve(kFlushBytes + 4096);
  }

  void real(double value) {
    if (ascii_) {
      separate();
      // Shortest representation that reads back to the same float or double.
      char* begin = text_.data();
      const auto result = doubles_ ? std::to_chars(begin, begin + text_.size(), value)
                                   : std::to_chars(begin, begin + text_.size(), toFloat(value));
      buffer_.append(begin, result.ptr);
    } else if (doubles_) {
      raw(value);
    } else {
      raw(toFloat(value));
    }
  }

  void byte(std::uint8_t value) {
    if (ascii_) {
      separate();
      buffer_ += std::to_string(value);
    } else {
      raw(value);
    }
  }

  void index(std::uint32_t value) {  // range-checked by checkMesh
    if (ascii_) {
      separate();
      buffer_ += std::to_string(value);
    } else {
      raw(static_cast<std::int32_t>(value));
    }
  }

  void endRecord() {
    if (ascii_) buffer_ += '\n';
    lineStart_ = true;
    if (buffer_.size() >= kFlushBytes) flush();
  }

  void flush() {
    out_.write(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
    buffer_.clear();
  }

 private:
  static constexpr std::size_t kFlushBytes = std::size_t{1} << 20;

  void separate() {
    if (!lineStart_) buffer_ += ' ';
    lineStart_ = false;
  }

  template <class T>
  void raw(T value) {
    auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(value);
    if constexpr (std::endian::native == std::endian::big) std::reverse(bytes.begin(), bytes.end());
    buffer_.append(bytes.data(), bytes.size());
  }

  std::ofstream& out_;
  bool ascii_;
  bool doubles_;
  bool lineStart_ = true;
  std::string buffer_;
  std::array<char, 64> text_{};
};

void writeBody(std::ofstream& out, const Cloud& cloud, const std::vector<Triangle>& triangles,
               const PlyWriteOptions& options) {
  std::vector<const std::vector<double>*> scalars;
  for (const auto& entry : cloud.scalars) scalars.push_back(&entry.second);

  Encoder encoder(out, options);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (int axis = 0; axis < 3; ++axis) encoder.real(cloud.positions[i][axis]);
    if (cloud.hasNormals()) {
      for (int axis = 0; axis < 3; ++axis) encoder.real(cloud.normals[i][axis]);
    }
    if (cloud.hasStrain()) encoder.real(cloud.strain[i]);
    for (const std::vector<double>* values : scalars) encoder.real((*values)[i]);
    if (cloud.hasColors()) {
      for (const std::uint8_t channel : cloud.colors[i]) encoder.byte(channel);
    }
    encoder.endRecord();
  }
  for (const Triangle& triangle : triangles) {
    encoder.byte(3);
    for (const std::uint32_t v : triangle.v) encoder.index(v);
    encoder.endRecord();
  }
  encoder.flush();
}

void writeAtomically(const fs::path& file, const Cloud& cloud, const std::vector<Triangle>& triangles,
                     const PlyWriteOptions& options) {
  // Bad input is refused before any file is touched.
  try {
    cloud.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("cannot write " + file.string() + ": " + e.what());
  }
  for (const auto& entry : cloud.scalars) checkScalarName(file, entry.first);
  checkTriangles(file, cloud.size(), triangles);

  AtomicFile output(file);
  const fs::path& temporary = output.temporaryPath();
  try {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) {
      throw std::runtime_error("cannot create temporary file " + temporary.string() + " (" +
                               std::generic_category().message(errno) + ")");
    }
    const std::string header = buildHeader(cloud, triangles, options);
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    writeBody(out, cloud, triangles, options);
    out.flush();
    if (!out) throw std::runtime_error("write to " + temporary.string() + " failed (disk full?)");
    out.close();
    if (out.fail()) throw std::runtime_error("closing " + temporary.string() + " failed");
    // (Surviving a power cut would also need fsync, which iostreams do not offer.)
    output.commit();
  } catch (const std::exception& e) {
    throw writeError(file, e.what());
  }
}

}  // namespace

void writePly(const std::filesystem::path& file, const Cloud& cloud, const PlyWriteOptions& options) {
  writeAtomically(file, cloud, {}, options);
}

void writePly(const std::filesystem::path& file, const Mesh& mesh, const PlyWriteOptions& options) {
  writeAtomically(file, mesh.vertices, mesh.triangles, options);
}

}  // namespace stampscan::fitting
