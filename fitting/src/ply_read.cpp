// Reading PLY data: each element's records in ASCII or binary (either byte order), after the header
// (ply_header.cpp). The vertex element becomes a Cloud, a `face` element becomes triangles, and
// everything else is skipped. Input is untrusted: every count is checked against the bytes that are
// really there before anything is sized from it, and every failure is an InputError saying where.
#include "io_detail.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string_view>
#include <type_traits>
#include <vector>

namespace stampscan::fitting {

using namespace detail;

namespace {

template <class T>
T loadValue(const char* bytes, bool swapBytes) {
  std::array<char, sizeof(T)> raw;
  std::memcpy(raw.data(), bytes, sizeof(T));
  if (swapBytes) std::reverse(raw.begin(), raw.end());
  return std::bit_cast<T>(raw);
}

double decode(ScalarType type, const char* bytes, bool swapBytes) {
  switch (type) {
    case ScalarType::Int8: return loadValue<std::int8_t>(bytes, swapBytes);
    case ScalarType::UInt8: return loadValue<std::uint8_t>(bytes, swapBytes);
    case ScalarType::Int16: return loadValue<std::int16_t>(bytes, swapBytes);
    case ScalarType::UInt16: return loadValue<std::uint16_t>(bytes, swapBytes);
    case ScalarType::Int32: return loadValue<std::int32_t>(bytes, swapBytes);
    case ScalarType::UInt32: return loadValue<std::uint32_t>(bytes, swapBytes);
    case ScalarType::Float32: return loadValue<float>(bytes, swapBytes);
    case ScalarType::Float64: return loadValue<double>(bytes, swapBytes);
  }
  return 0.0;
}

// ---- Data sources ---------------------------------------------------------------------------------
// Both sources offer the same calls, so one templated loop reads records from either.

// Thrown by a source when the input ends inside an element; the record loop turns it into an
// InputError saying how many records were complete.
struct OutOfData {};

class BinarySource {
 public:
  BinarySource(std::string_view bytes, std::size_t offset, bool swapBytes)
      : bytes_(bytes), pos_(offset), swapBytes_(swapBytes) {}

  std::size_t offset() const { return pos_; }
  std::size_t remaining() const { return bytes_.size() - pos_; }
  std::string where() const { return byteWhere(pos_); }
  std::string recordWhere() const { return byteWhere(recordStart_); }

  void beginRecord(const Element&) { recordStart_ = pos_; }
  void endRecord() {}

  double value(const Property&, ScalarType type) {
    const std::size_t size = sizeOf(type);
    if (remaining() < size) throw OutOfData{};
    const double result = decode(type, bytes_.data() + pos_, swapBytes_);
    pos_ += size;
    return result;
  }

  void skipItems(const Property& property, std::uint64_t count) {
    const std::size_t size = sizeOf(property.type);
    if (count > remaining() / size) throw OutOfData{};
    pos_ += static_cast<std::size_t>(count) * size;
  }

  void skipBytes(std::size_t count) { pos_ += count; }

  // Where data stand after the last record the header declares; nothing when the file ends there.
  std::optional<std::string> trailingData() const {
    if (remaining() == 0) return std::nullopt;
    return byteWhere(pos_) + " (" + std::to_string(remaining()) + " bytes)";
  }

 private:
  std::string_view bytes_;
  std::size_t pos_;
  std::size_t recordStart_ = 0;
  bool swapBytes_;
};

// One record a line; blank lines between records are tolerated.
class AsciiSource {
 public:
  AsciiSource(std::string_view bytes, std::size_t offset, std::size_t firstLine, const std::string& file)
      : bytes_(bytes), file_(file), pos_(offset), line_(firstLine - 1) {}

  std::size_t remaining() const { return bytes_.size() - pos_; }
  std::string where() const { return lineWhere(line_, tokenOffset_); }
  std::string recordWhere() const { return lineWhere(recordLine_, recordStart_); }

  void beginRecord(const Element& element) {
    element_ = &element;
    do {
      if (pos_ >= bytes_.size()) {
        recordLine_ = line_ + 1;
        recordStart_ = pos_;
        throw OutOfData{};
      }
      std::size_t end = bytes_.find('\n', pos_);
      if (end == std::string_view::npos) end = bytes_.size();
      ++line_;
      restOffset_ = pos_;
      rest_ = bytes_.substr(pos_, end - pos_);
      pos_ = std::min(end + 1, bytes_.size());
      skipBlanks();
    } while (rest_.empty());
    recordLine_ = line_;
    recordStart_ = restOffset_;
    tokenOffset_ = restOffset_;
  }

  void endRecord() {
    skipBlanks();
    if (!rest_.empty()) {
      tokenOffset_ = restOffset_;
      throw InputError(file_, where(), "too many values on the line for a " + element_->name + " record: " + excerpt(rest_));
    }
  }

  double value(const Property& property, ScalarType type) {
    skipBlanks();
    tokenOffset_ = restOffset_;
    std::size_t length = 0;
    while (length < rest_.size() && !isBlank(rest_[length])) ++length;
    if (length == 0) {
      throw InputError(file_, where(),
                       "too few values on the line: the " + element_->name + " record has no value for property '" +
                           property.name + "'");
    }
    const std::string_view token = rest_.substr(0, length);
    rest_.remove_prefix(length);
    restOffset_ += length;
    double result = 0.0;
    if (!parseNumber(token, result)) {
      throw InputError(file_, where(), "non-numeric value " + excerpt(token) + " for property '" + property.name + "'");
    }
    // A float property holds the nearest float, as it would in a binary file; beyond float's range
    // it saturates to infinity (the conversion itself would be undefined).
    if (type == ScalarType::Float32 && std::isfinite(result)) {
      result = std::abs(result) <= std::numeric_limits<float>::max() ? static_cast<double>(static_cast<float>(result))
                                                                      : std::copysign(HUGE_VAL, result);
    }
    return result;
  }

  void skipItems(const Property& property, std::uint64_t count) {
    for (std::uint64_t i = 0; i < count; ++i) value(property, property.type);
  }

  // The line of the first value after the last record the header declares; nothing when only
  // blanks follow.
  std::optional<std::string> trailingData() const {
    std::size_t line = line_;
    for (std::size_t at = pos_; at < bytes_.size(); ++at) {
      if (bytes_[at] == '\n') ++line;
      else if (!isBlank(bytes_[at]) && bytes_[at] != '\r') return lineWhere(line + 1, at);
    }
    return std::nullopt;
  }

 private:
  void skipBlanks() {
    std::size_t n = 0;
    while (n < rest_.size() && isBlank(rest_[n])) ++n;
    rest_.remove_prefix(n);
    restOffset_ += n;
  }

  std::string_view bytes_;
  const std::string& file_;
  std::size_t pos_;
  std::size_t line_;
  std::string_view rest_;       // unread part of the current line
  std::size_t restOffset_ = 0;  // file offset of rest_
  std::size_t tokenOffset_ = 0;
  std::size_t recordLine_ = 0;
  std::size_t recordStart_ = 0;
  const Element* element_ = nullptr;
};

// ---- Records --------------------------------------------------------------------------------------

std::string recordCount(const Element& element, std::uint64_t count) {
  const std::string n = std::to_string(count);
  if (element.name == "vertex") return n + (count == 1 ? " vertex" : " vertices");
  if (element.name == "face") return n + (count == 1 ? " face" : " faces");
  return n + " '" + element.name + "' record" + (count == 1 ? "" : "s");
}

std::string truncatedReason(const Element& element, std::uint64_t complete) {
  return "truncated " + element.name + " data: expected " + recordCount(element, element.count) + ", got " +
         std::to_string(complete);
}

// Binary only: a count the remaining bytes cannot hold is rejected before anything is sized from
// it. For fixed-size records the number of complete records is known without reading them.
void checkBinaryCount(const BinarySource& source, const Element& element, const std::string& file) {
  const std::size_t minBytes = element.minRecordBytes();
  if (minBytes == 0 || element.count <= source.remaining() / minBytes) return;
  if (!element.hasLists()) {
    const std::size_t complete = source.remaining() / minBytes;
    throw InputError(file, byteWhere(source.offset() + complete * minBytes), truncatedReason(element, complete));
  }
  // With lists, the read itself stops at the end of the data and reports the exact position.
}

// How many records to reserve room for: never more than the remaining bytes could hold.
std::size_t reserveFor(const Element& element, std::size_t remainingBytes, bool binary) {
  const std::size_t minBytes = binary ? std::max<std::size_t>(element.minRecordBytes(), 1) : 2;
  return static_cast<std::size_t>(std::min<std::uint64_t>(element.count, remainingBytes / minBytes + 1));
}

template <class Source>
std::uint64_t readListLength(Source& source, const Property& property, const std::string& file) {
  const double length = source.value(property, property.countType);
  // 2^40 bounds any list a real file holds and keeps the conversion below defined.
  if (!(length >= 0.0 && length <= 1099511627776.0) || length != std::floor(length)) {
    throw InputError(file, source.where(), "invalid list length " + formatNumber(length) + " for property '" + property.name + "'");
  }
  return static_cast<std::uint64_t>(length);
}

template <class Source, class ReadOne>
void forEachRecord(Source& source, const Element& element, const std::string& file, ReadOne&& readOne) {
  std::uint64_t complete = 0;
  try {
    for (; complete < element.count; ++complete) {
      source.beginRecord(element);
      readOne(complete);
      source.endRecord();
    }
  } catch (const OutOfData&) {
    throw InputError(file, source.recordWhere(), truncatedReason(element, complete));
  }
}

constexpr std::uint32_t kDropped = std::numeric_limits<std::uint32_t>::max();

struct MeshBuilder {
  const std::string& file;
  Mesh mesh;
  std::uint64_t fileVertexCount = 0;
  std::vector<std::uint32_t> keptIndex;  // file vertex index -> index in mesh.vertices, or kDropped
  std::size_t skippedNonfinite = 0;
};

// Where each vertex property goes; indices are into the element's property list.
struct VertexLayout {
  std::size_t x = 0, y = 0, z = 0;
  std::optional<std::array<std::size_t, 3>> normal;
  std::optional<std::array<std::size_t, 3>> color;
  std::optional<std::size_t> strain;
  std::vector<std::pair<std::size_t, std::vector<double>*>> scalars;
};

std::optional<std::size_t> findScalar(const Element& element, std::string_view name, const std::string& file) {
  for (std::size_t i = 0; i < element.properties.size(); ++i) {
    if (element.properties[i].name != name) continue;
    if (element.properties[i].isList) {
      throw InputError(file, element.declaredAt, "vertex property '" + std::string(name) + "' is a list, expected a number");
    }
    return i;
  }
  return std::nullopt;
}

// Finds a group such as nx ny nz, which must be present whole or not at all.
std::optional<std::array<std::size_t, 3>> findTriple(const Element& element, const std::array<std::string_view, 3>& names,
                                                     const std::string& file) {
  std::array<std::optional<std::size_t>, 3> found;
  for (std::size_t i = 0; i < 3; ++i) found[i] = findScalar(element, names[i], file);
  const auto present = std::count_if(found.begin(), found.end(), [](const auto& f) { return f.has_value(); });
  if (present == 0) return std::nullopt;
  if (present < 3) {
    throw InputError(file, element.declaredAt,
                     "vertex properties " + std::string(names[0]) + ", " + std::string(names[1]) + " and " +
                         std::string(names[2]) + " must be given all three or not at all");
  }
  return std::array<std::size_t, 3>{*found[0], *found[1], *found[2]};
}

VertexLayout layoutOf(const Element& element, Cloud& cloud, const std::string& file) {
  VertexLayout layout;
  const auto x = findScalar(element, "x", file);
  const auto y = findScalar(element, "y", file);
  const auto z = findScalar(element, "z", file);
  if (!x || !y || !z) {
    throw InputError(file, element.declaredAt,
                     std::string("vertex element lacks property '") + (!x ? "x" : !y ? "y" : "z") + "'");
  }
  layout.x = *x;
  layout.y = *y;
  layout.z = *z;
  layout.normal = findTriple(element, {"nx", "ny", "nz"}, file);
  layout.color = findTriple(element, {"red", "green", "blue"}, file);
  layout.strain = findScalar(element, "strain", file);
  static constexpr std::array<std::string_view, 10> kKnown{"x",  "y",      "z",   "nx",    "ny",
                                                           "nz", "strain", "red", "green", "blue"};
  for (std::size_t i = 0; i < element.properties.size(); ++i) {
    const Property& p = element.properties[i];
    if (p.isList || std::find(kKnown.begin(), kKnown.end(), p.name) != kKnown.end()) continue;
    layout.scalars.emplace_back(i, &cloud.scalars[p.name]);  // map nodes do not move
  }
  return layout;
}

// Colours are taken on the 0..255 scale whatever the stored type; out-of-range values are clamped.
std::uint8_t toColorByte(double value) {
  if (!(value > 0.0)) return 0;
  if (value >= 255.0) return 255;
  return static_cast<std::uint8_t>(std::lround(value));
}

template <class Source>
void readVertices(Source& source, const Element& element, MeshBuilder& builder, std::size_t reserve) {
  Cloud& cloud = builder.mesh.vertices;
  const VertexLayout layout = layoutOf(element, cloud, builder.file);
  cloud.positions.reserve(reserve);
  if (layout.normal) cloud.normals.reserve(reserve);
  if (layout.color) cloud.colors.reserve(reserve);
  if (layout.strain) cloud.strain.reserve(reserve);
  for (auto& scalar : layout.scalars) scalar.second->reserve(reserve);
  builder.keptIndex.reserve(reserve);

  std::vector<double> row(element.properties.size(), 0.0);
  forEachRecord(source, element, builder.file, [&](std::uint64_t) {
    for (std::size_t k = 0; k < element.properties.size(); ++k) {
      const Property& p = element.properties[k];
      if (p.isList) {
        source.skipItems(p, readListLength(source, p, builder.file));
      } else {
        row[k] = source.value(p, p.type);
      }
    }
    if (builder.keptIndex.size() == kDropped) {  // only a file of more than 50 GB gets here
      throw InputError(builder.file, source.recordWhere(), "more than 4294967294 vertices");
    }
    const Vec3 position(row[layout.x], row[layout.y], row[layout.z]);
    if (!position.allFinite()) {  // dropped with all its attributes, so the vectors stay aligned
      ++builder.skippedNonfinite;
      builder.keptIndex.push_back(kDropped);
      return;
    }
    builder.keptIndex.push_back(static_cast<std::uint32_t>(cloud.positions.size()));
    cloud.positions.push_back(position);
    if (const auto& n = layout.normal) cloud.normals.emplace_back(row[(*n)[0]], row[(*n)[1]], row[(*n)[2]]);
    if (const auto& c = layout.color) {
      cloud.colors.push_back({toColorByte(row[(*c)[0]]), toColorByte(row[(*c)[1]]), toColorByte(row[(*c)[2]])});
    }
    if (layout.strain) cloud.strain.push_back(row[*layout.strain]);
    for (auto& [index, values] : layout.scalars) values->push_back(row[index]);
  });
}

std::optional<std::size_t> findIndexList(const Element& element) {
  for (std::size_t i = 0; i < element.properties.size(); ++i) {
    const Property& p = element.properties[i];
    if (p.isList && (p.name == "vertex_indices" || p.name == "vertex_index")) return i;
  }
  return std::nullopt;
}

template <class Source>
void readFaces(Source& source, const Element& element, MeshBuilder& builder, std::size_t reserve) {
  const std::optional<std::size_t> indexList = findIndexList(element);
  std::vector<Triangle>& triangles = builder.mesh.triangles;
  triangles.reserve(reserve);
  std::vector<std::uint32_t> polygon;
  forEachRecord(source, element, builder.file, [&](std::uint64_t face) {
    for (std::size_t k = 0; k < element.properties.size(); ++k) {
      const Property& p = element.properties[k];
      if (!p.isList) {
        source.value(p, p.type);
        continue;
      }
      const std::uint64_t length = readListLength(source, p, builder.file);
      if (k != indexList) {
        source.skipItems(p, length);
        continue;
      }
      polygon.clear();
      for (std::uint64_t j = 0; j < length; ++j) {
        const double index = source.value(p, p.type);
        // The second bound keeps the conversion below defined when faces precede an absurd vertex count.
        if (!(index >= 0.0 && index < static_cast<double>(builder.fileVertexCount) && index < kDropped) ||
            index != std::floor(index)) {
          throw InputError(builder.file, source.where(),
                           "face " + std::to_string(face) + ": vertex index " + formatNumber(index) +
                               " out of range (the file has " + std::to_string(builder.fileVertexCount) + " vertices)");
        }
        polygon.push_back(static_cast<std::uint32_t>(index));
      }
      // Polygons become a fan of triangles around their first corner; fewer than 3 corners add none.
      for (std::size_t j = 1; j + 1 < polygon.size(); ++j) triangles.push_back({{polygon[0], polygon[j], polygon[j + 1]}});
    }
  });
}

template <class Source>
void skipElement(Source& source, const Element& element, const std::string& file) {
  forEachRecord(source, element, file, [&](std::uint64_t) {
    for (const Property& p : element.properties) {
      if (p.isList) {
        source.skipItems(p, readListLength(source, p, file));
      } else {
        source.value(p, p.type);
      }
    }
  });
}

template <class Source>
void readElements(Source& source, const Header& header, MeshBuilder& builder) {
  constexpr bool binary = std::is_same_v<Source, BinarySource>;
  for (const Element& element : header.elements) {
    // An element without properties has records of no bytes: nothing to read, however many. (A
    // vertex element without properties goes on, to fail for its missing x.)
    if (element.properties.empty() && element.name != "vertex") continue;
    if constexpr (binary) {
      checkBinaryCount(source, element, builder.file);
      if (!element.hasLists() && element.name != "vertex" && element.name != "face") {
        source.skipBytes(static_cast<std::size_t>(element.count) * element.minRecordBytes());  // checked above
        continue;
      }
    }
    const std::size_t reserve = reserveFor(element, source.remaining(), binary);
    if (element.name == "vertex") {
      readVertices(source, element, builder, reserve);
    } else if (element.name == "face" && findIndexList(element)) {
      readFaces(source, element, builder, reserve);
    } else {
      skipElement(source, element, builder.file);
    }
  }
  // Data past what the header declares: its counts are wrong (a file appended to, or a header
  // rewritten short), so what was read is not the file's whole content.
  if (const auto at = source.trailingData())
    throw InputError(builder.file, *at, "data after the last record the header declares: its element counts do not "
                                        "match the file");
}

// Faces may precede the vertices in the file, so dropped vertices are removed from them only at the end.
void dropFacesOfDroppedVertices(MeshBuilder& builder) {
  std::vector<Triangle>& triangles = builder.mesh.triangles;
  std::size_t kept = 0;
  for (const Triangle& t : triangles) {
    const Triangle mapped{{builder.keptIndex[t.v[0]], builder.keptIndex[t.v[1]], builder.keptIndex[t.v[2]]}};
    if (mapped.v[0] == kDropped || mapped.v[1] == kDropped || mapped.v[2] == kDropped) continue;
    triangles[kept++] = mapped;
  }
  triangles.resize(kept);
}

}  // namespace

Mesh parsePly(const std::string& bytes, const std::string& name, ReadReport* report) {
  const Header header = parsePlyHeader(bytes, name);
  const auto vertexElement = std::find_if(header.elements.begin(), header.elements.end(),
                                          [](const Element& e) { return e.name == "vertex"; });
  if (vertexElement == header.elements.end()) throw InputError(name, "header", "no vertex element: no points");
  if (vertexElement->count == 0) throw InputError(name, vertexElement->declaredAt, "no points (vertex count is 0)");

  MeshBuilder builder{name, {}, vertexElement->count, {}, 0};
  if (header.encoding == Encoding::Ascii) {
    AsciiSource source(bytes, header.dataOffset, header.dataLine, name);
    readElements(source, header, builder);
  } else {
    const bool fileIsLittle = header.encoding == Encoding::BinaryLittleEndian;
    const bool swapBytes = fileIsLittle != (std::endian::native == std::endian::little);
    BinarySource source(bytes, header.dataOffset, swapBytes);
    readElements(source, header, builder);
  }

  Cloud& cloud = builder.mesh.vertices;
  if (cloud.empty()) {
    throw InputError(name, "vertex data",
                     "no finite points: all " + std::to_string(builder.skippedNonfinite) +
                         " points have a non-finite coordinate");
  }
  if (builder.skippedNonfinite > 0) dropFacesOfDroppedVertices(builder);
  if (report) {
    report->points_read = cloud.size();
    report->skipped_nonfinite = builder.skippedNonfinite;
    report->faces_read = builder.mesh.triangles.size();
  }
  return std::move(builder.mesh);
}

Mesh readPlyMesh(const std::filesystem::path& file, ReadReport* report) {
  return parsePly(readWholeFile(file), file.string(), report);
}

Cloud readPly(const std::filesystem::path& file, ReadReport* report) {
  return std::move(readPlyMesh(file, report).vertices);
}

}  // namespace stampscan::fitting
