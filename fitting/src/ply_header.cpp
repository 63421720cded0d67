// InputError, the PLY header parser, and the helpers the PLY and text readers share.
#include "io_detail.hpp"

#include <array>
#include <charconv>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <system_error>
#include <unordered_set>

namespace stampscan::fitting {

namespace {

std::string joinMessage(const std::string& file, const std::string& where, const std::string& reason) {
  std::string message = file;
  for (const std::string* part : {&where, &reason}) {
    if (part->empty()) continue;
    if (!message.empty()) message += ": ";
    message += *part;
  }
  return message;
}

}  // namespace

InputError::InputError(const std::string& file, const std::string& where, const std::string& reason)
    : std::runtime_error(joinMessage(file, where, reason)), file_(file), where_(where), reason_(reason) {}

namespace detail {

std::string byteWhere(std::size_t offset) { return "byte " + std::to_string(offset); }
std::string lineWhere(std::size_t line, std::size_t offset) {
  return "line " + std::to_string(line) + ", byte " + std::to_string(offset);
}

std::string excerpt(std::string_view text, std::size_t maxLength) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out = "'";
  for (std::size_t i = 0; i < text.size() && i < maxLength; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xf];
    }
  }
  if (text.size() > maxLength) out += "...";
  return out + "'";
}

// std::from_chars is fast and locale-independent, but rejects the leading '+' some writers emit.
bool parseNumber(std::string_view token, double& value) {
  const char* first = token.data();
  const char* last = first + token.size();
  if (last - first > 1 && *first == '+' && first[1] != '-' && first[1] != '+') ++first;
  const auto [end, error] = std::from_chars(first, last, value);
  if (end != last) return false;
  if (error == std::errc::result_out_of_range) {
    // Valid syntax but beyond double's range: strtod gives the saturated value (+-inf or 0).
    value = std::strtod(std::string(first, last).c_str(), nullptr);
    return true;
  }
  return error == std::errc();
}

std::string formatNumber(double value) {
  std::array<char, 32> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return std::string(buffer.data(), result.ptr);
}

std::string readWholeFile(const std::filesystem::path& file) {
  std::error_code error;
  // Only regular files: a FIFO or a device would block the read or never end.
  const std::filesystem::file_type type = std::filesystem::status(file, error).type();
  if (type == std::filesystem::file_type::directory) throw InputError(file.string(), "", "is a directory, not a file");
  if (type != std::filesystem::file_type::regular && type != std::filesystem::file_type::not_found)
    throw InputError(file.string(), "", "is not a regular file (a FIFO, socket or device)");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string(), "", "cannot open file");
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  in.seekg(0, std::ios::beg);
  if (size < 0 || !in) throw InputError(file.string(), "", "cannot read file");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (in.gcount() != static_cast<std::streamsize>(size)) throw InputError(file.string(), "", "cannot read file");
  return bytes;
}

std::size_t sizeOf(ScalarType type) {
  switch (type) {
    case ScalarType::Int8:
    case ScalarType::UInt8: return 1;
    case ScalarType::Int16:
    case ScalarType::UInt16: return 2;
    case ScalarType::Int32:
    case ScalarType::UInt32:
    case ScalarType::Float32: return 4;
    case ScalarType::Float64: return 8;
  }
  return 8;
}

namespace {

std::vector<std::string_view> splitWords(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && isBlank(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !isBlank(line[i])) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

std::string_view trimRight(std::string_view text) {
  while (!text.empty() && isBlank(text.back())) text.remove_suffix(1);
  return text;
}

std::optional<ScalarType> scalarTypeNamed(std::string_view name) {
  struct Entry {
    std::string_view name;
    ScalarType type;
  };
  static constexpr std::array<Entry, 16> kTypes{{
      {"char", ScalarType::Int8},     {"int8", ScalarType::Int8},       {"uchar", ScalarType::UInt8},
      {"uint8", ScalarType::UInt8},   {"short", ScalarType::Int16},     {"int16", ScalarType::Int16},
      {"ushort", ScalarType::UInt16}, {"uint16", ScalarType::UInt16},   {"int", ScalarType::Int32},
      {"int32", ScalarType::Int32},   {"uint", ScalarType::UInt32},     {"uint32", ScalarType::UInt32},
      {"float", ScalarType::Float32}, {"float32", ScalarType::Float32}, {"double", ScalarType::Float64},
      {"float64", ScalarType::Float64},
  }};
  for (const Entry& entry : kTypes) {
    if (entry.name == name) return entry.type;
  }
  return std::nullopt;
}

ScalarType parseType(std::string_view word, const std::string& file, const std::string& where) {
  if (const auto type = scalarTypeNamed(word)) return *type;
  throw InputError(file, where, "unknown property type " + excerpt(word));
}

}  // namespace

Header parsePlyHeader(std::string_view bytes, const std::string& file) {
  if (bytes.empty()) throw InputError(file, byteWhere(0), "empty file");
  if (!bytes.starts_with("ply")) throw InputError(file, byteWhere(0), "not a PLY file: it does not start with 'ply'");

  Header header;
  // Sets rather than scans, so that a header of many thousand lines stays linear.
  std::unordered_set<std::string> elementNames;
  std::unordered_set<std::string> propertyNames;  // of the current element
  bool sawFormat = false;
  std::size_t pos = 0;
  std::size_t lineNumber = 0;
  while (true) {
    const std::size_t end = bytes.find('\n', pos);
    if (end == std::string_view::npos) {
      throw InputError(file, lineWhere(lineNumber + 1, pos), "truncated header: the file ends before end_header");
    }
    ++lineNumber;
    const std::string where = lineWhere(lineNumber, pos);
    const std::string_view line = trimRight(bytes.substr(pos, end - pos));  // also drops CRLF's '\r'
    pos = end + 1;
    if (lineNumber == 1) {
      if (line != "ply") throw InputError(file, where, "not a PLY file: the first line is " + excerpt(line));
      continue;
    }
    const std::vector<std::string_view> words = splitWords(line);
    if (words.empty() || words[0] == "comment" || words[0] == "obj_info") continue;
    const std::string_view keyword = words[0];
    if (keyword == "end_header") break;

    if (keyword == "format") {
      if (words.size() != 3) throw InputError(file, where, "malformed format line " + excerpt(line));
      if (sawFormat) throw InputError(file, where, "second format line");
      if (words[1] == "ascii") {
        header.encoding = Encoding::Ascii;
      } else if (words[1] == "binary_little_endian") {
        header.encoding = Encoding::BinaryLittleEndian;
      } else if (words[1] == "binary_big_endian") {
        header.encoding = Encoding::BinaryBigEndian;
      } else {
        throw InputError(file, where,
                         "unknown PLY format " + excerpt(words[1]) +
                             " (expected ascii, binary_little_endian or binary_big_endian)");
      }
      if (words[2] != "1.0" && words[2] != "1") {
        throw InputError(file, where, "unsupported PLY version " + excerpt(words[2]));
      }
      sawFormat = true;
    } else if (keyword == "element") {
      if (words.size() != 3) throw InputError(file, where, "malformed element line, expected 'element NAME COUNT'");
      Element element;
      element.name = std::string(words[1]);
      element.declaredAt = where;
      const char* last = words[2].data() + words[2].size();
      const auto [numberEnd, error] = std::from_chars(words[2].data(), last, element.count);
      if (error != std::errc() || numberEnd != last) {
        throw InputError(file, where, "element count " + excerpt(words[2]) + " is not a non-negative integer");
      }
      if (!elementNames.insert(element.name).second) throw InputError(file, where, "second element " + excerpt(words[1]));
      header.elements.push_back(std::move(element));
      propertyNames.clear();
    } else if (keyword == "property") {
      if (header.elements.empty()) throw InputError(file, where, "property line before any element line");
      Property property;
      if (words.size() == 5 && words[1] == "list") {
        property.isList = true;
        property.countType = parseType(words[2], file, where);
        property.type = parseType(words[3], file, where);
        if (!isInteger(property.countType)) throw InputError(file, where, "list length type must be an integer type");
        property.name = std::string(words[4]);
      } else if (words.size() == 3 && words[1] != "list") {
        property.type = parseType(words[1], file, where);
        property.name = std::string(words[2]);
      } else {
        throw InputError(file, where,
                         "malformed property line " + excerpt(line) +
                             ", expected 'property TYPE NAME' or 'property list COUNT_TYPE ITEM_TYPE NAME'");
      }
      Element& element = header.elements.back();
      if (!propertyNames.insert(property.name).second) {
        throw InputError(file, where, "second property " + excerpt(property.name) + " in element " + excerpt(element.name));
      }
      element.properties.push_back(std::move(property));
    } else {
      throw InputError(file, where, "unexpected header line " + excerpt(line) + " (missing end_header?)");
    }
  }
  if (!sawFormat) throw InputError(file, "header", "missing format line");
  header.dataOffset = pos;
  header.dataLine = lineNumber + 1;
  return header;
}

}  // namespace detail

}  // namespace stampscan::fitting
