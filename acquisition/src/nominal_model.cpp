// The nominal model's geometry helpers and its STL files. No Open CASCADE here (step_model.cpp has
// it): the STL reader is fuzzed on its own.
#include "stampscan/acquisition/nominal_model.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <unordered_map>

namespace stampscan::acquisition {

static_assert(std::endian::native == std::endian::little, "binary STL is little-endian; this reader copies it as is");

namespace {

using Vertex = std::array<double, 3>;

std::array<double, 3> sub(const Vertex& a, const Vertex& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
std::array<double, 3> cross(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const std::array<double, 3>& a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

// Merges vertices with bit-identical coordinates: STL repeats every vertex once per triangle.
class VertexMerger {
 public:
  explicit VertexMerger(NominalModel& model) : model_(model) {}
  std::uint32_t add(const Vertex& v) {
    Key key{};
    std::memcpy(key.bits.data(), v.data(), sizeof key.bits);
    const auto [it, inserted] = index_.try_emplace(key, static_cast<std::uint32_t>(model_.vertices.size()));
    if (inserted) model_.vertices.push_back(v);
    return it->second;
  }
  void triangle(const Vertex& a, const Vertex& b, const Vertex& c) { model_.triangles.push_back({add(a), add(b), add(c)}); }

 private:
  struct Key {
    std::array<std::uint64_t, 3> bits;
    bool operator==(const Key&) const = default;
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = 0x9e3779b97f4a7c15ULL;
      for (const std::uint64_t b : k.bits) h = (h ^ b) * 0x100000001b3ULL + (h >> 29);
      return static_cast<std::size_t>(h);
    }
  };
  NominalModel& model_;
  std::unordered_map<Key, std::uint32_t, Hash> index_;
};

constexpr std::size_t kBinaryHeader = 84, kBinaryFacet = 50;

std::uint32_t readU32(std::string_view bytes, std::size_t at) {
  std::uint32_t v = 0;
  std::memcpy(&v, bytes.data() + at, sizeof v);
  return v;
}

// The triangle count a binary header announces, when the size agrees with it.
bool looksBinary(std::string_view bytes) {
  if (bytes.size() < kBinaryHeader) return false;
  const std::uint64_t n = readU32(bytes, 80);
  return bytes.size() == kBinaryHeader + kBinaryFacet * n;
}

NominalModel parseBinary(std::string_view bytes, const std::string& name) {
  NominalModel model;
  model.source = name;
  const std::size_t n = readU32(bytes, 80);
  VertexMerger merger(model);
  model.triangles.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t at = kBinaryHeader + kBinaryFacet * k + 12;  // after the facet normal
    std::array<float, 9> f{};
    std::memcpy(f.data(), bytes.data() + at, sizeof f);
    std::array<Vertex, 3> v{};
    for (std::size_t i = 0; i < 3; ++i) {
      v[i] = {f[3 * i], f[3 * i + 1], f[3 * i + 2]};
      for (const double c : v[i])
        if (!std::isfinite(c))
          throw ModelError(name + ": triangle " + std::to_string(k + 1) + " has a coordinate that is not a finite number");
    }
    merger.triangle(v[0], v[1], v[2]);
  }
  return model;
}

// ASCII STL: "solid name / facet normal n n n / outer loop / vertex x y z (3x) / endloop /
// endfacet / ... / endsolid name", tokens separated by any white space. Several solids may follow
// one another; they make one model.
class AsciiReader {
 public:
  AsciiReader(std::string_view text, const std::string& name) : text_(text), name_(name) {}

  NominalModel read() {
    NominalModel model;
    model.source = name_;
    VertexMerger merger(model);
    expect("solid");
    skipLine();  // the solid's name, if any
    for (;;) {
      const std::string_view word = token();
      if (word.empty()) fail("ends inside a solid (no endsolid)");
      if (word == "endsolid") {
        skipLine();
        if (token().empty()) break;
        back();
        expect("solid");
        skipLine();
        continue;
      }
      if (word != "facet") fail("expected facet or endsolid, found " + shown(word));
      expect("normal");
      for (int i = 0; i < 3; ++i) number("facet normal");
      expect("outer");
      expect("loop");
      std::array<Vertex, 3> v{};
      for (Vertex& p : v) {
        expect("vertex");
        for (double& c : p) {
          c = number("vertex");
          if (!std::isfinite(c)) fail("vertex coordinate is not a finite number");
        }
      }
      expect("endloop");
      expect("endfacet");
      merger.triangle(v[0], v[1], v[2]);
    }
    return model;
  }

 private:
  // A token as the message shows it: quoted and cut short. (Appended rather than summed: GCC 12
  // warns falsely on the sum, -Wrestrict.)
  static std::string shown(std::string_view word) {
    if (word.empty()) return "the end of the file";
    std::string s = "\"";
    s.append(word.substr(0, 40));
    s += '"';
    return s;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw ModelError(name_ + ":" + std::to_string(line_) + ": ASCII STL " + what);
  }
  void skipSpace() {
    while (at_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[at_]))) {
      if (text_[at_] == '\n') ++line_;
      ++at_;
    }
  }
  std::string_view token() {
    skipSpace();
    last_ = at_;
    last_line_ = line_;
    const std::size_t begin = at_;
    while (at_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[at_]))) ++at_;
    return text_.substr(begin, at_ - begin);
  }
  void back() {
    at_ = last_;
    line_ = last_line_;
  }
  void skipLine() {
    while (at_ < text_.size() && text_[at_] != '\n') ++at_;
  }
  void expect(std::string_view word) {
    const std::string_view found = token();
    if (found != word)
      fail("expected " + shown(word) + ", found " + shown(found));
  }
  double number(const char* what) {
    const std::string_view word = token();
    std::string_view digits = word;
    if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);  // from_chars refuses a leading '+'
    double v = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (word.empty() || error != std::errc() || end != digits.data() + digits.size())
      fail(std::string(what) + " expects a number, found " + shown(word));
    return v;
  }

  std::string_view text_;
  const std::string& name_;
  std::size_t at_ = 0, last_ = 0;
  std::size_t line_ = 1, last_line_ = 1;
};

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::array<double, 3> unitNormal(const NominalModel& m, const std::array<std::uint32_t, 3>& t) {
  const std::array<double, 3> n = cross(sub(m.vertices[t[1]], m.vertices[t[0]]), sub(m.vertices[t[2]], m.vertices[t[0]]));
  const double len = norm(n);
  if (!(len > 0)) return {0, 0, 0};
  return {n[0] / len, n[1] / len, n[2] / len};
}

}  // namespace

Box3 NominalModel::bounds() const {
  Box3 box;
  if (vertices.empty()) return box;
  box.min = box.max = vertices.front();
  for (const Vertex& v : vertices)
    for (std::size_t i = 0; i < 3; ++i) {
      box.min[i] = std::min(box.min[i], v[i]);
      box.max[i] = std::max(box.max[i], v[i]);
    }
  return box;
}

double NominalModel::area() const {
  double sum = 0;
  for (const auto& t : triangles) sum += 0.5 * norm(cross(sub(vertices[t[1]], vertices[t[0]]), sub(vertices[t[2]], vertices[t[0]])));
  return sum;
}

void NominalModel::check(const std::string& name) const {
  if (triangles.empty()) throw ModelError(name + ": the model has no triangles");
  for (std::size_t k = 0; k < vertices.size(); ++k)
    for (const double c : vertices[k])
      if (!std::isfinite(c))
        throw ModelError(name + ": vertex " + std::to_string(k + 1) + " has a coordinate that is not a finite number");
  for (std::size_t k = 0; k < triangles.size(); ++k)
    for (const std::uint32_t i : triangles[k])
      if (i >= vertices.size())
        throw ModelError(name + ": triangle " + std::to_string(k + 1) + " refers to vertex " + std::to_string(i + 1) +
                         " of " + std::to_string(vertices.size()));
}

NominalModel parseStl(std::string_view bytes, const std::string& name) {
  NominalModel model;
  if (looksBinary(bytes)) {
    model = parseBinary(bytes, name);
  } else {
    std::size_t first = 0;
    while (first < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[first]))) ++first;
    if (bytes.substr(first, 5) == "solid") {
      try {
        model = AsciiReader(bytes, name).read();
      } catch (const ModelError& e) {
        // A binary file with "solid" in its header and the wrong size reads as broken ASCII; say both.
        if (bytes.size() < kBinaryHeader) throw;
        throw ModelError(std::string(e.what()) + " (nor is it a binary STL: " + std::to_string(bytes.size()) +
                         " bytes, where the " + std::to_string(readU32(bytes, 80)) + " triangles its header announces need " +
                         std::to_string(kBinaryHeader + kBinaryFacet * std::uint64_t{readU32(bytes, 80)}) + ")");
      }
    } else if (bytes.size() < kBinaryHeader) {
      throw ModelError(name + ": not an STL file: " + std::to_string(bytes.size()) +
                       " bytes, shorter than a binary STL's 84-byte header, and no \"solid\" of an ASCII STL");
    } else {
      const std::uint64_t n = readU32(bytes, 80);
      const std::uint64_t need = kBinaryHeader + kBinaryFacet * n;
      const std::uint64_t present = (bytes.size() - kBinaryHeader) / kBinaryFacet;
      if (bytes.size() < need)
        throw ModelError(name + ": binary STL truncated: " + std::to_string(n) + " triangles announced, " +
                         std::to_string(present) + " present (" + std::to_string(bytes.size()) + " of " + std::to_string(need) +
                         " bytes)");
      throw ModelError(name + ": binary STL has " + std::to_string(bytes.size() - need) + " bytes after the " +
                       std::to_string(n) + " triangles its header announces");
    }
  }
  model.check(name);
  return model;
}

NominalModel loadStl(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) throw ModelError(file.string() + ": the model file does not exist");
  if (!std::filesystem::is_regular_file(file, ec)) throw ModelError(file.string() + ": not a regular file, not a model file");
  std::ifstream in(file, std::ios::binary);
  if (!in.is_open()) throw ModelError(file.string() + ": cannot be opened");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw ModelError(file.string() + ": cannot be read");
  return parseStl(bytes, file.string());
}

std::string binaryStl(const NominalModel& model) {
  model.check(model.source);
  if (model.triangles.size() > std::numeric_limits<std::uint32_t>::max())
    throw ModelError(model.source + ": too many triangles for a binary STL");
  std::string out(kBinaryHeader + kBinaryFacet * model.triangles.size(), '\0');
  {
    // Not "solid...": a reader that goes by the first word would take the file for ASCII.
    static constexpr char kHeader[] = "binary STL, mm, nominal part model";
    std::memcpy(out.data(), kHeader, sizeof kHeader - 1);
    const auto n = static_cast<std::uint32_t>(model.triangles.size());
    std::memcpy(out.data() + 80, &n, sizeof n);
    for (std::size_t k = 0; k < model.triangles.size(); ++k) {
      const auto& t = model.triangles[k];
      const std::array<double, 3> normal = unitNormal(model, t);
      std::array<float, 12> f{};
      for (std::size_t i = 0; i < 3; ++i) f[i] = static_cast<float>(normal[i]);
      for (std::size_t v = 0; v < 3; ++v)
        for (std::size_t i = 0; i < 3; ++i) f[3 + 3 * v + i] = static_cast<float>(model.vertices[t[v]][i]);
      std::memcpy(out.data() + kBinaryHeader + kBinaryFacet * k, f.data(), sizeof f);  // attribute bytes stay 0
    }
  }
  return out;
}

void writeStl(const NominalModel& model, const std::filesystem::path& file, bool binary) {
  model.check(file.string());
  std::string out;
  if (binary) {
    out = binaryStl(model);
  } else {
    std::ostringstream o;
    o << "solid nominal\n";
    for (const auto& t : model.triangles) {
      const std::array<double, 3> n = unitNormal(model, t);
      o << "  facet normal " << fmt(n[0]) << ' ' << fmt(n[1]) << ' ' << fmt(n[2]) << "\n    outer loop\n";
      for (const std::uint32_t v : t) {
        const Vertex& p = model.vertices[v];
        o << "      vertex " << fmt(p[0]) << ' ' << fmt(p[1]) << ' ' << fmt(p[2]) << '\n';
      }
      o << "    endloop\n  endfacet\n";
    }
    o << "endsolid nominal\n";
    out = o.str();
  }
  fitting::writeFileAtomically(file, out);
}

NominalModel meshHeightGrid(const HeightGrid& grid) {
  if (grid.columns < 2 || grid.rows < 2 || grid.heights.size() != grid.columns * grid.rows)
    throw ModelError("height grid: needs at least 2 x 2 samples and one height per sample");
  NominalModel model;
  model.vertices.reserve(grid.columns * grid.rows);
  for (std::size_t j = 0; j < grid.rows; ++j)
    for (std::size_t i = 0; i < grid.columns; ++i)
      model.vertices.push_back({grid.x0 + static_cast<double>(i) * grid.dx, grid.y0 + static_cast<double>(j) * grid.dy,
                                grid.heights[j * grid.columns + i]});
  model.triangles.reserve(2 * (grid.columns - 1) * (grid.rows - 1));
  for (std::size_t j = 0; j + 1 < grid.rows; ++j)
    for (std::size_t i = 0; i + 1 < grid.columns; ++i) {
      const auto a = static_cast<std::uint32_t>(j * grid.columns + i);
      const auto b = a + 1;
      const auto c = static_cast<std::uint32_t>(a + grid.columns);
      const auto d = c + 1;
      model.triangles.push_back({a, b, d});  // counter-clockwise seen from +z
      model.triangles.push_back({a, d, c});
    }
  return model;
}

}  // namespace stampscan::acquisition
