// PLY reading and writing for clouds and meshes (ASCII, binary little- and big-endian; float or
// double). Vertex properties understood: x y z, nx ny nz, strain, red green blue; every other scalar
// vertex property is kept in Cloud::scalars by name; list properties and other elements are skipped.
// A `face` element with a `vertex_indices` (or `vertex_index`) list is read into a mesh.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace stampscan::fitting {

// Malformed input: names the file, where (byte offset, and line for ASCII parts), and what was wrong.
class InputError : public std::runtime_error {
 public:
  InputError(const std::string& file, const std::string& where, const std::string& reason);
  const std::string& file() const { return file_; }
  const std::string& where() const { return where_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string file_, where_, reason_;
};

struct ReadReport {
  std::size_t points_read = 0;         // points kept in the cloud
  std::size_t skipped_nonfinite = 0;   // points with a NaN or infinite coordinate, dropped
  std::size_t faces_read = 0;
};

enum class PlyFormat { Ascii, BinaryLittleEndian };
enum class PlyPrecision { Float, Double };

struct PlyWriteOptions {
  PlyFormat format = PlyFormat::BinaryLittleEndian;
  PlyPrecision precision = PlyPrecision::Float;  // for positions, normals and scalars
  std::string comment;                           // optional header comment (single line)
};

// Reads a PLY cloud. Throws InputError on malformed input, or when the file holds no point.
Cloud readPly(const std::filesystem::path& file, ReadReport* report = nullptr);
// Reads a PLY mesh (a cloud of vertices and the `face` element, which may be absent).
Mesh readPlyMesh(const std::filesystem::path& file, ReadReport* report = nullptr);
// Parses PLY bytes held in memory; `name` is used in error messages. Used by the fuzzer.
Mesh parsePly(const std::string& bytes, const std::string& name, ReadReport* report = nullptr);

// Writes atomically: to a temporary file beside `file`, renamed over it only when complete, so a
// failure leaves no partial output. Throws std::runtime_error naming the file on I/O failure.
void writePly(const std::filesystem::path& file, const Cloud& cloud, const PlyWriteOptions& options = {});
void writePly(const std::filesystem::path& file, const Mesh& mesh, const PlyWriteOptions& options = {});

}  // namespace stampscan::fitting
