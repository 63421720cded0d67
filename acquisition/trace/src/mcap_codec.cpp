// Field layouts follow the record tables of the MCAP specification (https://mcap.dev/spec); each
// function names its record. Parsers accept content longer than the fields they know, because the
// spec lets records grow new fields at their end ("Readers should ignore any unknown fields").
#include "mcap_codec.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstring>

namespace stampscan::trace {

std::string opcodeName(std::uint8_t opcode) {
  static constexpr const char* kNames[] = {"Header",          "Footer",     "Schema",         "Channel",
                                           "Message",         "Chunk",      "Message Index",  "Chunk Index",
                                           "Attachment",      "Attachment Index", "Statistics", "Metadata",
                                           "Metadata Index",  "Summary Offset",   "Data End"};
  if (opcode >= 0x01 && opcode <= 0x0F) return kNames[opcode - 1];
  static constexpr char kHex[] = "0123456789abcdef";
  return std::string("unknown (0x") + kHex[opcode >> 4] + kHex[opcode & 0xF] + ")";
}

std::string compressionName(Compression compression) {
  switch (compression) {
    case Compression::Zstd: return "zstd";
    case Compression::Lz4: return "lz4";
    case Compression::None: break;
  }
  return "";
}

namespace detail {

std::uint32_t crc32(std::uint32_t crc, Bytes bytes) {
  // zlib returns the initial value (0) for a null buffer, which an empty span may have.
  if (bytes.empty()) return crc;
  // crc32_z takes a size_t length, so multi-GB spans need no splitting.
  return static_cast<std::uint32_t>(
      ::crc32_z(crc, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<z_size_t>(bytes.size())));
}

bool isMagic(Bytes bytes) {
  return bytes.size() == kMcapMagic.size() &&
         std::equal(bytes.begin(), bytes.end(), kMcapMagic.begin(),
                    [](std::byte a, std::uint8_t b) { return std::to_integer<std::uint8_t>(a) == b; });
}

std::uint64_t readU64(Bytes b) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | std::to_integer<std::uint64_t>(b[static_cast<std::size_t>(i)]);
  return v;
}

std::uint32_t readU32(Bytes b) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | std::to_integer<std::uint32_t>(b[static_cast<std::size_t>(i)]);
  return v;
}

// --- RecordBuilder ------------------------------------------------------------------------------

std::size_t RecordBuilder::begin(Opcode opcode) {
  const std::size_t start = bytes_.size();
  u8(static_cast<std::uint8_t>(opcode));
  u64(0);  // content length, patched by end()
  return start;
}

void RecordBuilder::end(std::size_t start) {
  std::uint64_t length = bytes_.size() - start - kRecordPrefix;
  for (std::size_t i = 0; i < 8; ++i) {
    bytes_[start + 1 + i] = static_cast<std::byte>(length & 0xFF);
    length >>= 8;
  }
}

void RecordBuilder::little(std::uint64_t v, int n) {
  for (int i = 0; i < n; ++i) {
    bytes_.push_back(static_cast<std::byte>(v & 0xFF));
    v >>= 8;
  }
}

// resize + memcpy rather than vector::insert: GCC 12 at -O3 warns (wrongly, -Wstringop-overflow)
// about a range insert into a vector that may be empty.
void RecordBuilder::raw(Bytes b) {
  if (b.empty()) return;
  const std::size_t at = bytes_.size();
  bytes_.resize(at + b.size());
  std::memcpy(bytes_.data() + at, b.data(), b.size());
}

void RecordBuilder::string(std::string_view s) {
  u32(static_cast<std::uint32_t>(s.size()));
  raw(asBytes(s));
}

void RecordBuilder::bytes32(Bytes b) {
  u32(static_cast<std::uint32_t>(b.size()));
  raw(b);
}

void RecordBuilder::keyValues(const KeyValues& map) {
  std::uint64_t length = 0;
  for (const auto& [key, value] : map) length += 8 + key.size() + value.size();
  u32(static_cast<std::uint32_t>(length));  // Map: uint32 byte length of the entries that follow
  for (const auto& [key, value] : map) {
    string(key);
    string(value);
  }
}

void RecordBuilder::idMap(const std::map<std::uint16_t, std::uint64_t>& map) {
  u32(static_cast<std::uint32_t>(map.size() * 10));
  for (const auto& [id, value] : map) {
    u16(id);
    u64(value);
  }
}

// --- Cursor -------------------------------------------------------------------------------------

bool Cursor::little(std::uint64_t& v, std::size_t n) {
  if (remaining() < n) return false;
  v = 0;
  for (std::size_t i = n; i-- > 0;) v = (v << 8) | std::to_integer<std::uint64_t>(bytes_[pos_ + i]);
  pos_ += n;
  return true;
}

bool Cursor::u8(std::uint8_t& v) {
  std::uint64_t x = 0;
  if (!little(x, 1)) return false;
  v = static_cast<std::uint8_t>(x);
  return true;
}
bool Cursor::u16(std::uint16_t& v) {
  std::uint64_t x = 0;
  if (!little(x, 2)) return false;
  v = static_cast<std::uint16_t>(x);
  return true;
}
bool Cursor::u32(std::uint32_t& v) {
  std::uint64_t x = 0;
  if (!little(x, 4)) return false;
  v = static_cast<std::uint32_t>(x);
  return true;
}
bool Cursor::u64(std::uint64_t& v) { return little(v, 8); }

bool Cursor::take(std::size_t n, Bytes& b) {
  if (remaining() < n) return false;
  b = bytes_.subspan(pos_, n);
  pos_ += n;
  return true;
}

bool Cursor::string(std::string& s) {
  std::uint32_t n = 0;
  Bytes b;
  if (!u32(n) || !take(n, b)) return false;
  s.assign(reinterpret_cast<const char*>(b.data()), b.size());
  return true;
}

bool Cursor::bytes32(std::vector<std::byte>& out) {
  std::uint32_t n = 0;
  Bytes b;
  if (!u32(n) || !take(n, b)) return false;
  out.assign(b.begin(), b.end());
  return true;
}

bool Cursor::keyValues(KeyValues& map) {
  std::uint32_t n = 0;
  Bytes entries;
  if (!u32(n) || !take(n, entries)) return false;
  Cursor inner(entries);
  map.clear();
  while (inner.remaining() > 0) {
    std::string key, value;
    if (!inner.string(key) || !inner.string(value)) return false;
    map[std::move(key)] = std::move(value);
  }
  return true;
}

bool Cursor::idMap(std::map<std::uint16_t, std::uint64_t>& map) {
  std::uint32_t n = 0;
  Bytes entries;
  if (!u32(n) || !take(n, entries) || n % 10 != 0) return false;
  Cursor inner(entries);
  map.clear();
  while (inner.remaining() > 0) {
    std::uint16_t id = 0;
    std::uint64_t value = 0;
    if (!inner.u16(id) || !inner.u64(value)) return false;
    map[id] = value;
  }
  return true;
}

// --- records ------------------------------------------------------------------------------------

void appendHeader(RecordBuilder& out, const Header& h) {  // Header: profile, library
  const std::size_t r = out.begin(Opcode::Header);
  out.string(h.profile);
  out.string(h.library);
  out.end(r);
}

void appendSchema(RecordBuilder& out, const Schema& s) {  // Schema: id, name, encoding, data
  const std::size_t r = out.begin(Opcode::Schema);
  out.u16(s.id);
  out.string(s.name);
  out.string(s.encoding);
  out.bytes32(s.data);
  out.end(r);
}

void appendChannel(RecordBuilder& out, const Channel& c) {  // Channel: id, schema_id, topic, encoding, metadata
  const std::size_t r = out.begin(Opcode::Channel);
  out.u16(c.id);
  out.u16(c.schema_id);
  out.string(c.topic);
  out.string(c.message_encoding);
  out.keyValues(c.metadata);
  out.end(r);
}

void appendMessage(RecordBuilder& out, std::uint16_t channel, std::uint32_t sequence, std::uint64_t log_time,
                   std::uint64_t publish_time, Bytes data) {  // Message: the data runs to the record's end
  const std::size_t r = out.begin(Opcode::Message);
  out.u16(channel);
  out.u32(sequence);
  out.u64(log_time);
  out.u64(publish_time);
  out.raw(data);
  out.end(r);
}

void appendMessageIndex(RecordBuilder& out, std::uint16_t channel,
                        const std::vector<std::pair<std::uint64_t, std::uint64_t>>& entries) {
  // Message Index: channel_id, then Array<Tuple<Timestamp, uint64>> of (log_time, offset into the
  // uncompressed chunk records).
  const std::size_t r = out.begin(Opcode::MessageIndex);
  out.u16(channel);
  out.u32(static_cast<std::uint32_t>(entries.size() * 16));
  for (const auto& [time, offset] : entries) {
    out.u64(time);
    out.u64(offset);
  }
  out.end(r);
}

void appendChunkIndex(RecordBuilder& out, const ChunkIndex& c) {
  const std::size_t r = out.begin(Opcode::ChunkIndex);
  out.u64(c.message_start_time);
  out.u64(c.message_end_time);
  out.u64(c.chunk_start_offset);
  out.u64(c.chunk_length);
  out.idMap(c.message_index_offsets);
  out.u64(c.message_index_length);
  out.string(c.compression);
  out.u64(c.compressed_size);
  out.u64(c.uncompressed_size);
  out.end(r);
}

void appendAttachmentIndex(RecordBuilder& out, const AttachmentIndex& a) {
  const std::size_t r = out.begin(Opcode::AttachmentIndex);
  out.u64(a.offset);
  out.u64(a.length);
  out.u64(a.log_time);
  out.u64(a.create_time);
  out.u64(a.data_size);
  out.string(a.name);
  out.string(a.media_type);
  out.end(r);
}

void appendStatistics(RecordBuilder& out, const Statistics& s) {
  const std::size_t r = out.begin(Opcode::Statistics);
  out.u64(s.message_count);
  out.u16(s.schema_count);
  out.u32(s.channel_count);
  out.u32(s.attachment_count);
  out.u32(s.metadata_count);
  out.u32(s.chunk_count);
  out.u64(s.message_start_time);
  out.u64(s.message_end_time);
  out.idMap(s.channel_message_counts);
  out.end(r);
}

void appendMetadata(RecordBuilder& out, std::string_view name, const KeyValues& map) {
  const std::size_t r = out.begin(Opcode::Metadata);
  out.string(name);
  out.keyValues(map);
  out.end(r);
}

void appendMetadataIndex(RecordBuilder& out, const MetadataIndex& m) {
  const std::size_t r = out.begin(Opcode::MetadataIndex);
  out.u64(m.offset);
  out.u64(m.length);
  out.string(m.name);
  out.end(r);
}

void appendSummaryOffset(RecordBuilder& out, const SummaryOffset& s) {
  const std::size_t r = out.begin(Opcode::SummaryOffset);
  out.u8(s.group_opcode);
  out.u64(s.group_start);
  out.u64(s.group_length);
  out.end(r);
}

void appendDataEnd(RecordBuilder& out, std::uint32_t data_section_crc) {
  const std::size_t r = out.begin(Opcode::DataEnd);
  out.u32(data_section_crc);
  out.end(r);
}

bool parseHeader(Bytes content, Header& h) {
  Cursor c(content);
  return c.string(h.profile) && c.string(h.library);
}

bool parseFooter(Bytes content, Footer& f) {
  Cursor c(content);
  return c.u64(f.summary_start) && c.u64(f.summary_offset_start) && c.u32(f.summary_crc);
}

bool parseSchema(Bytes content, Schema& s) {
  Cursor c(content);
  return c.u16(s.id) && c.string(s.name) && c.string(s.encoding) && c.bytes32(s.data);
}

bool parseChannel(Bytes content, Channel& ch) {
  Cursor c(content);
  return c.u16(ch.id) && c.u16(ch.schema_id) && c.string(ch.topic) && c.string(ch.message_encoding) &&
         c.keyValues(ch.metadata);
}

bool parseStatistics(Bytes content, Statistics& s) {
  Cursor c(content);
  return c.u64(s.message_count) && c.u16(s.schema_count) && c.u32(s.channel_count) && c.u32(s.attachment_count) &&
         c.u32(s.metadata_count) && c.u32(s.chunk_count) && c.u64(s.message_start_time) &&
         c.u64(s.message_end_time) && c.idMap(s.channel_message_counts);
}

bool parseChunkIndex(Bytes content, ChunkIndex& ci) {
  Cursor c(content);
  return c.u64(ci.message_start_time) && c.u64(ci.message_end_time) && c.u64(ci.chunk_start_offset) &&
         c.u64(ci.chunk_length) && c.idMap(ci.message_index_offsets) && c.u64(ci.message_index_length) &&
         c.string(ci.compression) && c.u64(ci.compressed_size) && c.u64(ci.uncompressed_size);
}

bool parseAttachmentIndex(Bytes content, AttachmentIndex& a) {
  Cursor c(content);
  return c.u64(a.offset) && c.u64(a.length) && c.u64(a.log_time) && c.u64(a.create_time) && c.u64(a.data_size) &&
         c.string(a.name) && c.string(a.media_type);
}

bool parseMetadata(Bytes content, std::string& name, KeyValues& map) {
  Cursor c(content);
  return c.string(name) && c.keyValues(map);
}

bool parseMetadataIndex(Bytes content, MetadataIndex& m) {
  Cursor c(content);
  return c.u64(m.offset) && c.u64(m.length) && c.string(m.name);
}

bool parseSummaryOffset(Bytes content, SummaryOffset& s) {
  Cursor c(content);
  return c.u8(s.group_opcode) && c.u64(s.group_start) && c.u64(s.group_length);
}

bool parseDataEnd(Bytes content, std::uint32_t& data_section_crc) {
  Cursor c(content);
  return c.u32(data_section_crc);
}

bool parseMessageIndex(Bytes content, std::uint16_t& channel,
                       std::vector<std::pair<std::uint64_t, std::uint64_t>>& entries) {
  Cursor c(content);
  std::uint32_t n = 0;
  Bytes array;
  if (!c.u16(channel) || !c.u32(n) || !c.take(n, array) || n % 16 != 0) return false;
  entries.clear();
  entries.reserve(n / 16);
  for (std::size_t i = 0; i < array.size(); i += 16)
    entries.emplace_back(readU64(array.subspan(i, 8)), readU64(array.subspan(i + 8, 8)));
  return true;
}

bool parseMessage(Bytes content, MessageView& m) {
  Cursor c(content);
  if (!c.u16(m.channel_id) || !c.u32(m.sequence) || !c.u64(m.log_time) || !c.u64(m.publish_time)) return false;
  m.data = content.subspan(kMessagePrefix);  // spec: the message data is the rest of the record
  return true;
}

ParseResult parseChunkHeader(Bytes prefix, std::uint64_t content_length, ChunkHeader& h) {
  // Chunk: message_start_time, message_end_time, uncompressed_size, uncompressed_crc, compression
  // (String), records (uint64 length-prefixed Bytes).
  Cursor c(prefix);
  std::uint32_t name_length = 0;
  if (!c.u64(h.message_start_time) || !c.u64(h.message_end_time) || !c.u64(h.uncompressed_size) ||
      !c.u32(h.uncompressed_crc) || !c.u32(name_length))
    return content_length <= prefix.size() ? ParseResult::kBad : ParseResult::kNeedMore;
  if (28 + std::uint64_t{name_length} + 8 > content_length) return ParseResult::kBad;
  Bytes name;
  if (!c.take(name_length, name) || !c.u64(h.records_size)) return ParseResult::kNeedMore;
  h.compression.assign(reinterpret_cast<const char*>(name.data()), name.size());
  h.records_offset = c.position();
  if (h.records_size > content_length - h.records_offset) return ParseResult::kBad;
  return ParseResult::kOk;
}

ParseResult parseAttachmentHeader(Bytes prefix, std::uint64_t content_length, AttachmentHeader& a) {
  // Attachment: log_time, create_time, name, media_type, data (uint64 length-prefixed), crc (uint32).
  Cursor c(prefix);
  std::uint32_t n = 0;
  Bytes b;
  const auto need = [&](std::uint64_t upto) {
    return upto > content_length ? ParseResult::kBad : ParseResult::kNeedMore;
  };
  if (!c.u64(a.log_time) || !c.u64(a.create_time) || !c.u32(n)) return need(20);
  if (!c.take(n, b)) return need(20 + std::uint64_t{n});
  a.name.assign(reinterpret_cast<const char*>(b.data()), b.size());
  const std::uint64_t at = c.position();
  if (!c.u32(n)) return need(at + 4);
  if (!c.take(n, b)) return need(at + 4 + n);
  a.media_type.assign(reinterpret_cast<const char*>(b.data()), b.size());
  if (!c.u64(a.data_size)) return need(c.position() + 8);
  a.data_offset = c.position();
  if (a.data_size > content_length - a.data_offset || content_length - a.data_offset - a.data_size < 4)
    return ParseResult::kBad;
  return ParseResult::kOk;
}

}  // namespace detail
}  // namespace stampscan::trace
