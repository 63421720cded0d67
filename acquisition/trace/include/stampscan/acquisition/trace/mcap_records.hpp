// The MCAP record types shared by the trace writer and reader (https://mcap.dev/spec, major version
// "0"). Field names follow the spec's record tables; times are uint64 nanoseconds of the clock named
// by the channel (the spec's Timestamp type), offsets are bytes from the start of the file.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace stampscan::trace {

// Spec "Magic": 0x89 'M' 'C' 'A' 'P' then the major version '0', then "\r\n"; at both ends of a file.
inline constexpr std::array<std::uint8_t, 8> kMcapMagic{0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};

// Spec "Records": one opcode byte, a uint64 content length, the content. 0x01-0x7F are reserved for
// the format, 0x80-0xFF for application extensions (readers skip those).
enum class Opcode : std::uint8_t {
  Header = 0x01,
  Footer = 0x02,
  Schema = 0x03,
  Channel = 0x04,
  Message = 0x05,
  Chunk = 0x06,
  MessageIndex = 0x07,
  ChunkIndex = 0x08,
  Attachment = 0x09,
  AttachmentIndex = 0x0A,
  Statistics = 0x0B,
  Metadata = 0x0C,
  MetadataIndex = 0x0D,
  SummaryOffset = 0x0E,
  DataEnd = 0x0F,
};

// The spec's name for an opcode ("Chunk", "Data End", ...), or "unknown (0xNN)".
std::string opcodeName(std::uint8_t opcode);

// Chunk compression; the spec's strings are "" (none), "zstd" and "lz4" (LZ4 frame format).
enum class Compression { None, Zstd, Lz4 };
std::string compressionName(Compression compression);  // "", "zstd", "lz4"

using KeyValues = std::map<std::string, std::string>;  // the spec's Map<string, string>

struct Header {      // spec "Header (op=0x01)"
  std::string profile;
  std::string library;
};

struct Schema {      // spec "Schema (op=0x03)"; id 0 is invalid and means "no schema" on a channel
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::vector<std::byte> data;
};

struct Channel {     // spec "Channel (op=0x04)"
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;
  KeyValues metadata;
};

struct Statistics {  // spec "Statistics (op=0x0B)"
  std::uint64_t message_count = 0;
  std::uint16_t schema_count = 0;
  std::uint32_t channel_count = 0;
  std::uint32_t attachment_count = 0;
  std::uint32_t metadata_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::map<std::uint16_t, std::uint64_t> channel_message_counts;
};

struct ChunkIndex {  // spec "Chunk Index (op=0x08)"
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::uint64_t chunk_start_offset = 0;
  std::uint64_t chunk_length = 0;  // the whole Chunk record, opcode and length prefix included
  std::map<std::uint16_t, std::uint64_t> message_index_offsets;  // channel -> Message Index record offset
  std::uint64_t message_index_length = 0;
  std::string compression;
  std::uint64_t compressed_size = 0;
  std::uint64_t uncompressed_size = 0;
};

struct AttachmentIndex {  // spec "Attachment Index (op=0x0A)"
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  std::uint64_t log_time = 0;
  std::uint64_t create_time = 0;
  std::uint64_t data_size = 0;
  std::string name;
  std::string media_type;
};

struct MetadataIndex {  // spec "Metadata Index (op=0x0D)"
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  std::string name;
};

struct SummaryOffset {  // spec "Summary Offset (op=0x0E)"
  std::uint8_t group_opcode = 0;
  std::uint64_t group_start = 0;
  std::uint64_t group_length = 0;
};

struct Footer {  // spec "Footer (op=0x02)"
  std::uint64_t summary_start = 0;         // 0: no summary section
  std::uint64_t summary_offset_start = 0;  // 0: no summary offset section
  std::uint32_t summary_crc = 0;           // 0: not available
};

}  // namespace stampscan::trace
