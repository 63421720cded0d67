// Byte-level encoding of MCAP records (spec "Serialization": little-endian integers; String and the
// uint32-length-prefixed Bytes, Array and Map types), shared by the writer and the reader. Parsing
// never reads outside the span it is given and reports malformed content by returning false.
#pragma once

#include "stampscan/acquisition/trace/mcap_records.hpp"

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace stampscan::trace::detail {

using Bytes = std::span<const std::byte>;

inline constexpr std::size_t kRecordPrefix = 1 + 8;       // opcode + uint64 content length
inline constexpr std::size_t kFooterContent = 8 + 8 + 4;  // spec "Footer": never extended
inline constexpr std::size_t kFooterAndMagic = kRecordPrefix + kFooterContent + 8;
inline constexpr std::size_t kDataEndRecord = kRecordPrefix + 4;
inline constexpr std::size_t kMessagePrefix = 2 + 4 + 8 + 8;  // channel_id, sequence, log_time, publish_time

// CRC-32 as used throughout MCAP (the zlib / ISO-HDLC polynomial), continued from `crc` (0 to start).
std::uint32_t crc32(std::uint32_t crc, Bytes bytes);

inline Bytes asBytes(std::string_view s) { return {reinterpret_cast<const std::byte*>(s.data()), s.size()}; }
bool isMagic(Bytes bytes);  // exactly the 8 magic bytes

// Appends encoded fields to a byte vector; records are opened with begin() and their content length
// patched in by end(), so a record is built in one pass.
class RecordBuilder {
 public:
  std::vector<std::byte>& bytes() { return bytes_; }
  void clear() { bytes_.clear(); }

  std::size_t begin(Opcode opcode);  // returns the record's start, for end()
  void end(std::size_t start);

  void u8(std::uint8_t v) { bytes_.push_back(static_cast<std::byte>(v)); }
  void u16(std::uint16_t v) { little(v, 2); }
  void u32(std::uint32_t v) { little(v, 4); }
  void u64(std::uint64_t v) { little(v, 8); }
  void raw(Bytes b);
  void string(std::string_view s);  // spec String: uint32 length + UTF-8
  void bytes32(Bytes b);            // uint32 length-prefixed Bytes
  void keyValues(const KeyValues& map);                          // Map<string, string>
  void idMap(const std::map<std::uint16_t, std::uint64_t>& map);  // Map<uint16, uint64>

 private:
  void little(std::uint64_t v, int n);
  std::vector<std::byte> bytes_;
};

// Reads fields from a span; a getter returns false, without moving, when its field does not fit.
class Cursor {
 public:
  explicit Cursor(Bytes bytes) : bytes_(bytes) {}
  bool u8(std::uint8_t& v);
  bool u16(std::uint16_t& v);
  bool u32(std::uint32_t& v);
  bool u64(std::uint64_t& v);
  bool string(std::string& s);
  bool bytes32(std::vector<std::byte>& b);
  bool take(std::size_t n, Bytes& b);
  bool keyValues(KeyValues& map);
  bool idMap(std::map<std::uint16_t, std::uint64_t>& map);
  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return bytes_.size() - pos_; }

 private:
  bool little(std::uint64_t& v, std::size_t n);
  Bytes bytes_;
  std::size_t pos_ = 0;
};

std::uint64_t readU64(Bytes b);  // b has at least 8 bytes
std::uint32_t readU32(Bytes b);  // b has at least 4 bytes

// --- whole records: append (writer) and parse the content after the 9-byte prefix (reader) --------
void appendHeader(RecordBuilder& out, const Header& h);
void appendSchema(RecordBuilder& out, const Schema& s);
void appendChannel(RecordBuilder& out, const Channel& c);
void appendMessage(RecordBuilder& out, std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
                   std::uint64_t publish_time, Bytes data);
void appendMessageIndex(RecordBuilder& out, std::uint16_t channel,
                        const std::vector<std::pair<std::uint64_t, std::uint64_t>>& entries);
void appendChunkIndex(RecordBuilder& out, const ChunkIndex& c);
void appendAttachmentIndex(RecordBuilder& out, const AttachmentIndex& a);
void appendStatistics(RecordBuilder& out, const Statistics& s);
void appendMetadata(RecordBuilder& out, std::string_view name, const KeyValues& map);
void appendMetadataIndex(RecordBuilder& out, const MetadataIndex& m);
void appendSummaryOffset(RecordBuilder& out, const SummaryOffset& s);
void appendDataEnd(RecordBuilder& out, std::uint32_t data_section_crc);

bool parseHeader(Bytes content, Header& h);
bool parseFooter(Bytes content, Footer& f);
bool parseSchema(Bytes content, Schema& s);
bool parseChannel(Bytes content, Channel& c);
bool parseStatistics(Bytes content, Statistics& s);
bool parseChunkIndex(Bytes content, ChunkIndex& c);
bool parseAttachmentIndex(Bytes content, AttachmentIndex& a);
bool parseMetadata(Bytes content, std::string& name, KeyValues& map);
bool parseMetadataIndex(Bytes content, MetadataIndex& m);
bool parseSummaryOffset(Bytes content, SummaryOffset& s);
bool parseDataEnd(Bytes content, std::uint32_t& data_section_crc);
bool parseMessageIndex(Bytes content, std::uint16_t& channel,
                       std::vector<std::pair<std::uint64_t, std::uint64_t>>& entries);

struct MessageView {  // spec "Message (op=0x05)"; data points into the parsed content
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;
  std::uint64_t publish_time = 0;
  Bytes data;
};
bool parseMessage(Bytes content, MessageView& m);

// Spec "Chunk (op=0x06)" up to its records field, which may not be in memory yet (a large or cut
// chunk). Parsed from a prefix of the content: kNeedMore when the prefix is too short to tell.
struct ChunkHeader {
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::uint64_t uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;
  std::string compression;
  std::uint64_t records_size = 0;     // the uint64 length prefix of `records`
  std::size_t records_offset = 0;     // where `records` starts in the content
};
enum class ParseResult { kOk, kNeedMore, kBad };
ParseResult parseChunkHeader(Bytes content_prefix, std::uint64_t content_length, ChunkHeader& c);

// Spec "Attachment (op=0x09)" up to its data, which is streamed rather than held (attachments may be large).
struct AttachmentHeader {
  std::uint64_t log_time = 0;
  std::uint64_t create_time = 0;
  std::string name;
  std::string media_type;
  std::uint64_t data_size = 0;
  std::size_t data_offset = 0;  // in the content; the uint32 crc follows the data
};
ParseResult parseAttachmentHeader(Bytes content_prefix, std::uint64_t content_length, AttachmentHeader& a);

}  // namespace stampscan::trace::detail
