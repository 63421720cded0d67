#include "mcap_scan.hpp"

#include "mcap_chunk.hpp"

#include <algorithm>
#include <limits>
#include <utility>

namespace stampscan::trace::detail {

namespace {
// Schemas, channels, metadata and message indexes longer than this are taken for a damaged length.
constexpr std::uint64_t kMaxSmallRecord = std::uint64_t{256} << 20;
constexpr std::size_t kMaxDamageEntries = 10000;  // a garbage file must not make an endless report

bool knownOpcode(std::uint8_t op) { return op >= 0x01 && op <= 0x0F; }
constexpr std::uint8_t op(Opcode o) { return static_cast<std::uint8_t>(o); }
std::string num(std::uint64_t n) { return std::to_string(n); }
std::uint64_t plus(std::uint64_t a, std::uint64_t b) {  // saturating: lengths come from untrusted bytes
  return a > std::numeric_limits<std::uint64_t>::max() - b ? std::numeric_limits<std::uint64_t>::max() : a + b;
}
bool isMagicPrefix(Bytes bytes) {
  for (std::size_t i = 0; i < bytes.size() && i < kMcapMagic.size(); ++i)
    if (std::to_integer<std::uint8_t>(bytes[i]) != kMcapMagic[i]) return false;
  return bytes.size() <= kMcapMagic.size();
}
}  // namespace

Scanner::Scanner(ByteSource& source, const MessageCallback& callback, const ReadOptions& options,
                 const std::map<std::uint16_t, Channel>* summary_channels, TraceHealth& health)
    : src_(source), callback_(callback), options_(options), summary_channels_(summary_channels), h_(health),
      size_(source.size()) {
  h_.file_size = size_;
}

void Scanner::run() {
  detectTrailer();
  if (readStart()) scanData();
}

// A file that ends with a Footer record and the magic is complete: a record running past its end is
// damage, not a cut. When the summary CRC also holds (or is absent) and a Data End sits where the
// footer says the summary starts, that offset bounds the data section for the scan.
void Scanner::detectTrailer() {
  if (size_ < kMcapMagic.size() + kFooterAndMagic) return;
  const Bytes tail = src_.view(size_ - kFooterAndMagic, kFooterAndMagic);
  if (tail.size() != kFooterAndMagic || !isMagic(tail.subspan(kFooterAndMagic - 8)) ||
      std::to_integer<std::uint8_t>(tail[0]) != op(Opcode::Footer) || readU64(tail.subspan(1, 8)) != kFooterContent)
    return;
  parseFooter(tail.subspan(kRecordPrefix, kFooterContent), footer_);
  footer_offset_ = size_ - kFooterAndMagic;
  trailer_valid_ = true;
  std::uint64_t data_end = 0;
  if (footer_.summary_start != 0) {
    if (footer_.summary_start < kMcapMagic.size() + kDataEndRecord || footer_.summary_start > footer_offset_) return;
    data_end = footer_.summary_start - kDataEndRecord;
    if (footer_.summary_crc != 0 && crcOver(footer_.summary_start, footer_offset_ + kRecordPrefix + 16) != footer_.summary_crc)
      return;
  } else if (footer_.summary_offset_start == 0) {
    data_end = footer_offset_ - kDataEndRecord;
  } else {
    return;
  }
  const Bytes record = src_.view(data_end, kRecordPrefix);
  if (record.size() == kRecordPrefix && std::to_integer<std::uint8_t>(record[0]) == op(Opcode::DataEnd) &&
      readU64(record.subspan(1, 8)) == 4)
    data_end_offset_ = data_end;
}

// Spec "Magic" then "Header": the first record after the magic must be the Header.
bool Scanner::readStart() {
  const Bytes magic = src_.view(0, kMcapMagic.size());
  if (magic.size() < kMcapMagic.size()) {
    if (isMagicPrefix(magic)) {
      truncate("magic", 0, kMcapMagic.size(), magic.size());
    } else {
      h_.not_mcap = true;
      damage(0, DamageKind::BadMagic, "not an MCAP file: it does not start with the MCAP magic");
    }
    return false;
  }
  const bool magic_ok = isMagic(magic);
  const Bytes head = src_.view(kMcapMagic.size(), kRecordPrefix);
  const std::uint64_t available = size_ - kMcapMagic.size() - kRecordPrefix;
  if (!magic_ok) {
    // Damaged first bytes in front of an intact Header are damage; anything else is another format.
    const bool header_follows = head.size() == kRecordPrefix && std::to_integer<std::uint8_t>(head[0]) == op(Opcode::Header) &&
                                readU64(head.subspan(1, 8)) <= std::min(available, kMaxSmallRecord);
    h_.not_mcap = !header_follows;
    damage(0, DamageKind::BadMagic,
           header_follows ? "the file does not start with the MCAP magic" : "not an MCAP file: it does not start with the MCAP magic");
    if (!header_follows) return false;
  }
  pos_ = kMcapMagic.size();
  record_start_ = pos_;
  if (head.size() < kRecordPrefix) {
    truncate("Header", pos_, kRecordPrefix, head.size());
    return false;
  }
  const auto opcode = std::to_integer<std::uint8_t>(head[0]);
  const std::uint64_t length = readU64(head.subspan(1, 8));
  if (opcode != op(Opcode::Header)) {
    damage(pos_, DamageKind::BadRecord, "expected the Header record at byte 8, found " + opcodeName(opcode));
    return true;  // the scan deals with whatever is there
  }
  if (length > available) {
    if (!trailer_valid_) {
      truncate("Header", pos_, plus(kRecordPrefix, length), kRecordPrefix + available);
      return false;
    }
    lostFraming(pos_, "Header record length " + num(length) + " runs past the end of the file", DamageKind::BadLength);
    return true;
  }
  Header header;
  if (parseHeader(src_.view(pos_ + kRecordPrefix, static_cast<std::size_t>(length)), header)) h_.header = header;
  else damage(pos_, DamageKind::BadRecord, "malformed Header record");
  pos_ += kRecordPrefix + length;
  return true;
}

void Scanner::scanData() {
  while (!h_.stopped) {
    crcTo(pos_);
    if (pos_ >= size_) {
      if (!h_.truncated) truncate("next record", pos_, kRecordPrefix, 0);
      return;
    }
    const Bytes head = src_.view(pos_, kRecordPrefix);
    if (head.size() < kRecordPrefix) {
      truncate("record header", pos_, kRecordPrefix, head.size());
      return;
    }
    const auto opcode = std::to_integer<std::uint8_t>(head[0]);
    const std::uint64_t length = readU64(head.subspan(1, 8));
    const std::uint64_t available = size_ - pos_ - kRecordPrefix;
    if (length > available) {
      // Without a footer at the end this is the cut record of a file that ends early, unless a
      // record that validates follows within its claimed length: then the length was damaged.
      if (!trailer_valid_ && opcode != 0) {
        if (const std::optional<std::uint64_t> anchor = findAnchor(pos_ + 1)) {
          damage(pos_, DamageKind::BadLength,
                 opcodeName(opcode) + " record length " + num(length) + " runs past the end of the file; resumed at the " +
                     "valid record at byte " + num(*anchor));
          pos_ = record_start_ = *anchor;
          record_vouched_ = true;
          vouched_end_ = *anchor + 1;
          continue;
        }
        if (opcode == op(Opcode::Chunk)) recoverCutChunk(length, available);
        truncate(opcodeName(opcode), pos_, plus(kRecordPrefix, length), kRecordPrefix + available);
        return;
      }
      lostFraming(pos_, opcodeName(opcode) + " record length " + num(length) + " runs past the end of the file",
                  DamageKind::BadLength);
      continue;
    }
    const std::uint64_t end = pos_ + kRecordPrefix + length;
    if (data_end_offset_ && pos_ != *data_end_offset_ && end > *data_end_offset_) {
      lostFraming(pos_, opcodeName(opcode) + " record at byte " + num(pos_) + " (length " + num(length) +
                            ") runs into the summary section at byte " + num(*data_end_offset_),
                  DamageKind::BadLength);
      continue;
    }
    if (!handleRecord(opcode, length)) return;
  }
}

// Handles one data-section record. Returns false when the data section is over (Data End or a
// Footer reached) or the callback stopped the scan.
bool Scanner::handleRecord(std::uint8_t opcode, std::uint64_t length) {
  const std::uint64_t start = pos_, end = pos_ + kRecordPrefix + length;
  record_start_ = start;
  record_vouched_ = false;
  if (opcode != op(Opcode::MessageIndex) && opcode != op(Opcode::Chunk)) last_chunk_damaged_ = false;
  if (!knownOpcode(opcode)) {
    // Spec: unknown opcodes are skipped. But a damaged opcode looks the same, so the skip is
    // trusted only when a plausible record follows.
    if (opcode == 0 || !plausibleRecordAt(end)) {
      lostFraming(start, "invalid record (opcode 0x" + std::string(1, "0123456789abcdef"[opcode >> 4]) +
                             std::string(1, "0123456789abcdef"[opcode & 0xF]) + ", length " + num(length) + ")",
                  DamageKind::BadRecord);
      return true;
    }
    ++h_.unknown_records;
    pos_ = end;
    return true;
  }
  const bool small = opcode == op(Opcode::Schema) || opcode == op(Opcode::Channel) ||
                     opcode == op(Opcode::Metadata) || opcode == op(Opcode::MessageIndex);
  if (small && length > kMaxSmallRecord) {
    lostFraming(start, opcodeName(opcode) + " record length " + num(length) + " is not plausible", DamageKind::BadLength);
    return true;
  }
  switch (static_cast<Opcode>(opcode)) {
    case Opcode::Header:
      damage(start, DamageKind::MisplacedRecord, "a second Header record");
      break;
    case Opcode::Footer:
      damage(start, DamageKind::MissingDataEnd, "Footer reached without a Data End record");
      handleFooter(start, length, std::nullopt);
      return false;
    case Opcode::Schema:
      storeSchema(src_.view(start + kRecordPrefix, static_cast<std::size_t>(length)), start);
      break;
    case Opcode::Channel:
      storeChannel(src_.view(start + kRecordPrefix, static_cast<std::size_t>(length)), start);
      break;
    case Opcode::Metadata: {
      MetadataInfo info;
      info.offset = start;
      if (parseMetadata(src_.view(start + kRecordPrefix, static_cast<std::size_t>(length)), info.name, info.metadata))
        h_.metadata.push_back(std::move(info));
      else damage(start, DamageKind::BadRecord, "malformed Metadata record");
      break;
    }
    case Opcode::Message: handleMessage(length); break;
    case Opcode::Chunk: handleChunk(length); break;
    case Opcode::MessageIndex: handleMessageIndex(length); break;
    case Opcode::Attachment: handleAttachment(length); break;
    case Opcode::DataEnd: handleDataEnd(length); return false;
    default:
      damage(start, DamageKind::MisplacedRecord, opcodeName(opcode) + " record in the data section");
      break;
  }
  if (pos_ == start && record_start_ == start) pos_ = end;  // (a handler that lost the framing moved on itself)
  return !h_.stopped;
}

void Scanner::handleChunk(std::uint64_t length) {
  const std::uint64_t start = pos_;
  last_chunk_damaged_ = true;  // until it decodes
  const auto fail = [&](DamageKind kind, const std::string& what) {
    damage(start, kind, what + ": its messages are not delivered");
    ++h_.chunks_damaged;
  };
  if (length > plus(options_.max_chunk_bytes, 1 << 16)) {
    fail(DamageKind::ChunkUndecodable, "Chunk record of " + num(length) + " bytes, more than accepted");
    return;
  }
  const Bytes content = src_.view(start + kRecordPrefix, static_cast<std::size_t>(length));
  ChunkHeader header;
  if (parseChunkHeader(content, length, header) != ParseResult::kOk) {
    fail(DamageKind::BadRecord, "malformed Chunk record");
    return;
  }
  const DecodedChunk chunk = decodeChunk(content, header, options_.max_chunk_bytes, buffer_);
  if (!chunk.ok) {
    fail(chunk.kind, chunk.what);
    return;
  }
  last_chunk_damaged_ = false;
  record_vouched_ = chunk.verified;
  vouched_end_ = start + kRecordPrefix + header.records_offset + header.records_size;
  ++h_.chunks;
  h_.chunk_compressed_bytes += header.records_size;
  h_.chunk_uncompressed_bytes += header.uncompressed_size;
  h_.compressions.insert(header.compression);
  deliverRecords(chunk.records, chunk.verified, false);
}

// The last record of a cut file is a chunk: deliver the complete records its bytes decode to.
void Scanner::recoverCutChunk(std::uint64_t length, std::uint64_t available) {
  const Bytes content = src_.view(pos_ + kRecordPrefix, static_cast<std::size_t>(available));
  ChunkHeader header;
  if (parseChunkHeader(content, length, header) != ParseResult::kOk || header.records_offset > content.size()) return;
  const Bytes present = content.subspan(header.records_offset,
                                        std::min<std::size_t>(content.size() - header.records_offset,
                                                              static_cast<std::size_t>(header.records_size)));
  record_start_ = pos_;
  deliverRecords(decodeCutChunk(present, header, options_.max_chunk_bytes, buffer_), false, true);
}

void Scanner::deliverRecords(Bytes records, bool verified, bool cut) {
  const std::uint64_t chunk = record_start_;
  const std::size_t stop = forEachRecord(records, [&](std::uint8_t opcode, Bytes content, std::size_t at) {
    if (opcode == op(Opcode::Message)) {
      MessageView m;
      if (parseMessage(content, m)) return deliver(m, chunk, verified);
      damage(chunk, DamageKind::BadRecord, "malformed Message record at offset " + num(at) + " in the chunk");
    } else if (opcode == op(Opcode::Schema)) {
      storeSchema(content, chunk);
    } else if (opcode == op(Opcode::Channel)) {
      storeChannel(content, chunk);
    } else if (knownOpcode(opcode)) {
      damage(chunk, DamageKind::MisplacedRecord, opcodeName(opcode) + " record inside a chunk");
    } else {
      ++h_.unknown_records;
    }
    return true;
  });
  if (!cut && !h_.stopped && stop != records.size())
    damage(chunk, DamageKind::BadRecord,
           "the chunk's records end in " + num(records.size() - stop) + " bytes that are not a whole record");
}

bool Scanner::deliver(const MessageView& m, std::uint64_t record_offset, bool verified) {
  ++h_.messages_found;
  if (!verified) ++h_.messages_unverified;
  const Channel* ch = channel(m.channel_id);
  if (!ch && unknown_channels_.insert(m.channel_id).second)
    damage(record_offset, DamageKind::UnknownChannel,
           "messages on channel " + num(m.channel_id) + ", which no Channel record defines");
  if (!options_.channels.empty() && !options_.channels.count(m.channel_id)) return true;
  if (!options_.topics.empty() && (!ch || !options_.topics.count(ch->topic))) return true;
  if (m.log_time < options_.start_time || m.log_time > options_.end_time) return true;
  if (!callback_) return true;
  TraceMessage t;
  t.channel_id = m.channel_id;
  t.sequence = m.sequence;
  t.log_time = m.log_time;
  t.publish_time = m.publish_time;
  t.data = m.data;
  t.channel = ch;
  t.record_offset = record_offset;
  t.verified = verified;
  ++h_.messages_delivered;
  if (!callback_(t)) h_.stopped = true;
  return !h_.stopped;
}

const Channel* Scanner::channel(std::uint16_t id) const {
  if (const auto it = h_.channels.find(id); it != h_.channels.end()) return &it->second;
  if (summary_channels_) {
    if (const auto it = summary_channels_->find(id); it != summary_channels_->end()) return &it->second;
  }
  return nullptr;
}

// Spec "Schema"/"Channel": any two records with one id must be identical; a schema id of 0 is
// invalid and ignored.
void Scanner::storeSchema(Bytes content, std::uint64_t offset) {
  Schema s;
  if (!parseSchema(content, s)) return damage(offset, DamageKind::BadRecord, "malformed Schema record");
  if (s.id == 0) return;
  const auto [it, added] = h_.schemas.emplace(s.id, s);
  if (!added && (it->second.name != s.name || it->second.encoding != s.encoding || it->second.data != s.data))
    damage(offset, DamageKind::BadRecord, "Schema " + num(s.id) + " redefined differently");
}

void Scanner::storeChannel(Bytes content, std::uint64_t offset) {
  Channel c;
  if (!parseChannel(content, c)) return damage(offset, DamageKind::BadRecord, "malformed Channel record");
  const auto [it, added] = h_.channels.emplace(c.id, c);
  if (!added && (it->second.topic != c.topic || it->second.schema_id != c.schema_id ||
                 it->second.message_encoding != c.message_encoding || it->second.metadata != c.metadata))
    damage(offset, DamageKind::BadRecord, "Channel " + num(c.id) + " redefined differently");
}

void Scanner::damage(std::uint64_t offset, DamageKind kind, std::string what) {
  if (h_.damage.size() < kMaxDamageEntries) h_.damage.push_back({offset, kind, std::move(what)});
  else if (h_.damage.size() == kMaxDamageEntries)
    h_.damage.push_back({offset, kind, "more damage follows, not listed"});
}

void Scanner::truncate(std::string record, std::uint64_t at, std::uint64_t needed, std::uint64_t present) {
  h_.truncated = Truncation{size_, std::move(record), at, needed, present};
}

void Scanner::crcTo(std::uint64_t to) {
  if (to <= crc_pos_) return;
  while (crc_pos_ < to) {
    const Bytes piece = src_.view(crc_pos_, static_cast<std::size_t>(std::min<std::uint64_t>(to - crc_pos_, 1 << 20)));
    if (piece.empty()) return;
    crc_ = crc32(crc_, piece);
    crc_pos_ += piece.size();
  }
}

std::uint32_t Scanner::crcOver(std::uint64_t from, std::uint64_t to) {
  std::uint32_t crc = 0;
  while (from < to) {
    const Bytes piece = src_.view(from, static_cast<std::size_t>(std::min<std::uint64_t>(to - from, 1 << 20)));
    if (piece.empty()) break;
    crc = crc32(crc, piece);
    from += piece.size();
  }
  return crc;
}

}  // namespace stampscan::trace::detail
