// Internal to the fitting library's readers, not part of its interface: the PLY header model and
// its parser, and the small helpers the PLY and text readers share for messages, numbers and files.
#pragma once

#include "stampscan/fitting/ply_io.hpp"

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::fitting::detail {

// ---- Shared helpers -------------------------------------------------------------------------------

// Locations for InputError::where(): "byte 1234", "line 17, byte 345".
std::string byteWhere(std::size_t offset);
std::string lineWhere(std::size_t line, std::size_t offset);
// Quotes a piece of untrusted input for a message: printable ASCII only, and not too long.
std::string excerpt(std::string_view text, std::size_t maxLength = 40);
// Parses a whole token as a double: locale-independent, also "+1", "nan", "inf"; values beyond
// double's range saturate. False if the token is not entirely a number.
bool parseNumber(std::string_view token, double& value);
// Shortest text that reads back as the same double.
std::string formatNumber(double value);
// The whole file in memory; an InputError naming the file if it cannot be opened or read.
std::string readWholeFile(const std::filesystem::path& file);

inline bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// ---- PLY header -----------------------------------------------------------------------------------

enum class ScalarType : std::uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

std::size_t sizeOf(ScalarType type);
inline bool isInteger(ScalarType type) { return type != ScalarType::Float32 && type != ScalarType::Float64; }

struct Property {
  std::string name;
  ScalarType type = ScalarType::Float32;  // the item type, for a list
  bool isList = false;
  ScalarType countType = ScalarType::UInt8;
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  std::string declaredAt;  // header location, for messages about the element as a whole

  // The fewest bytes one binary record can take (each list may be empty).
  std::size_t minRecordBytes() const {
    std::size_t bytes = 0;
    for (const Property& p : properties) bytes += sizeOf(p.isList ? p.countType : p.type);
    return bytes;
  }
  bool hasLists() const {
    return std::any_of(properties.begin(), properties.end(), [](const Property& p) { return p.isList; });
  }
};

enum class Encoding { Ascii, BinaryLittleEndian, BinaryBigEndian };

struct Header {
  Encoding encoding = Encoding::Ascii;
  std::vector<Element> elements;
  std::size_t dataOffset = 0;  // first byte after the end_header line
  std::size_t dataLine = 0;    // the line number that byte starts, for ASCII data
};

// Parses everything up to and including end_header; InputError (naming `file`) if malformed.
Header parsePlyHeader(std::string_view bytes, const std::string& file);

}  // namespace stampscan::fitting::detail
