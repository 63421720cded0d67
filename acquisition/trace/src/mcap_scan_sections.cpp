// The scan's other records (messages outside chunks, message indexes, attachments), the end of the
// data section and the summary, and resynchronisation after the framing is lost.
#include "mcap_chunk.hpp"
#include "mcap_scan.hpp"

#include <algorithm>
#include <limits>
#include <optional>

namespace stampscan::trace::detail {

namespace {
constexpr std::size_t kAttachmentHeaderView = std::size_t{1} << 20;
constexpr std::size_t kResyncBlock = std::size_t{1} << 16;
std::string num(std::uint64_t n) { return std::to_string(n); }
constexpr std::uint8_t op(Opcode o) { return static_cast<std::uint8_t>(o); }
}  // namespace

// A message outside a chunk: no CRC vouches for it, so it is delivered only on a channel that a
// Channel record defined (a misread length lands on garbage that rarely names a known channel).
void Scanner::handleMessage(std::uint64_t length) {
  const std::uint64_t start = pos_;
  if (length > options_.max_chunk_bytes) {
    lostFraming(start, "Message record length " + num(length) + " is not plausible", DamageKind::BadLength);
    return;
  }
  MessageView m;
  if (!parseMessage(src_.view(start + kRecordPrefix, static_cast<std::size_t>(length)), m)) {
    damage(start, DamageKind::BadRecord, "Message record shorter than its 22-byte header");
    return;
  }
  if (!channel(m.channel_id)) {
    ++h_.messages_lost;
    if (unknown_channels_.insert(m.channel_id).second)
      damage(start, DamageKind::UnknownChannel,
             "messages on channel " + num(m.channel_id) + ", which no Channel record defines, are not delivered");
    return;
  }
  deliver(m, start, false);
}

// Spec "Message Index": they follow their chunk; after a damaged chunk they tell how much was lost.
void Scanner::handleMessageIndex(std::uint64_t length) {
  std::uint16_t channel_id = 0;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> entries;
  if (!parseMessageIndex(src_.view(pos_ + kRecordPrefix, static_cast<std::size_t>(length)), channel_id, entries)) {
    damage(pos_, DamageKind::BadRecord, "malformed Message Index record");
    return;
  }
  if (last_chunk_damaged_) h_.messages_lost += entries.size();
}

Scanner::AttachmentCheck Scanner::checkAttachment(std::uint64_t at, std::uint64_t length, AttachmentInfo* info) {
  AttachmentHeader a;
  const Bytes head = src_.view(at + kRecordPrefix, static_cast<std::size_t>(std::min<std::uint64_t>(length, kAttachmentHeaderView)));
  if (parseAttachmentHeader(head, length, a) != ParseResult::kOk) return AttachmentCheck::kMalformed;
  // Spec "Attachment": the crc covers every field before it; the data is streamed, never held whole.
  const std::uint64_t crc_at = at + kRecordPrefix + a.data_offset + a.data_size;
  const Bytes stored_bytes = src_.view(crc_at, 4);
  if (stored_bytes.size() < 4) return AttachmentCheck::kMalformed;
  const std::uint32_t stored = readU32(stored_bytes);
  const std::uint32_t computed = stored == 0 ? 0 : crcOver(at + kRecordPrefix, crc_at);
  const AttachmentCheck result =
      stored == 0 ? AttachmentCheck::kNoCrc : (stored == computed ? AttachmentCheck::kOk : AttachmentCheck::kMismatch);
  if (info) {
    info->offset = at;
    info->name = a.name;
    info->media_type = a.media_type;
    info->log_time = a.log_time;
    info->create_time = a.create_time;
    info->data_size = a.data_size;
    info->crc_checked = result == AttachmentCheck::kOk;
  }
  return result;
}

void Scanner::handleAttachment(std::uint64_t length) {
  AttachmentInfo info;
  const AttachmentCheck check = checkAttachment(pos_, length, &info);
  if (check == AttachmentCheck::kMalformed) {
    damage(pos_, DamageKind::BadRecord, "malformed Attachment record");
    return;
  }
  if (check == AttachmentCheck::kMismatch)
    damage(pos_, DamageKind::AttachmentCrcMismatch, "attachment '" + info.name + "': CRC mismatch");
  record_vouched_ = check == AttachmentCheck::kOk;
  vouched_end_ = pos_ + kRecordPrefix + length;
  h_.attachments.push_back(std::move(info));
}

// Spec "Data End": its CRC covers every byte of the file before it, leading magic and Header included.
void Scanner::handleDataEnd(std::uint64_t length) {
  crcTo(pos_);
  std::uint32_t stored = 0;
  if (!parseDataEnd(src_.view(pos_ + kRecordPrefix, static_cast<std::size_t>(length)), stored)) {
    damage(pos_, DamageKind::BadRecord, "malformed Data End record");
  } else {
    h_.data_end_found = true;
    if (stored != 0 && stored == crc_) h_.data_crc_checked = true;
    else if (stored != 0)
      damage(pos_, DamageKind::DataSectionCrcMismatch,
             "data section CRC mismatch over bytes 0.." + num(pos_) + " (stored " + num(stored) + ", computed " +
                 num(crc_) + ")");
  }
  walkSummary(pos_ + kRecordPrefix + length);
}

// Spec "Summary Section": only Schema, Channel, Chunk Index, Attachment Index, Statistics, Metadata
// Index, then Summary Offset records, then the Footer. Their CRC is checked at the Footer; each
// record is parsed as well, so that a summary without a CRC is still checked.
void Scanner::walkSummary(std::uint64_t start) {
  std::uint64_t p = start;
  while (true) {
    if (p >= size_) return truncate("Footer", p, kFooterAndMagic, 0);
    const Bytes head = src_.view(p, kRecordPrefix);
    if (head.size() < kRecordPrefix) return truncate("record header", p, kRecordPrefix, head.size());
    const auto opcode = std::to_integer<std::uint8_t>(head[0]);
    const std::uint64_t length = readU64(head.subspan(1, 8));
    const std::uint64_t available = size_ - p - kRecordPrefix;
    if (opcode == op(Opcode::Footer)) {
      if (length > available && !trailer_valid_)
        return truncate("Footer", p, kRecordPrefix + std::min(length, size_), kRecordPrefix + available);
      return handleFooter(p, std::min(length, available), start);
    }
    if (length > available || (trailer_valid_ && p + kRecordPrefix + length > footer_offset_)) {
      if (!trailer_valid_)
        return truncate(opcodeName(opcode), p, kRecordPrefix + std::min(length, size_), kRecordPrefix + available);
      damage(p, DamageKind::BadLength, opcodeName(opcode) + " record length " + num(length) + " runs past the Footer");
      return handleFooter(footer_offset_, kFooterContent, start);
    }
    const Bytes content = src_.view(p + kRecordPrefix, static_cast<std::size_t>(std::min<std::uint64_t>(length, std::uint64_t{1} << 30)));
    bool parsed = true;
    switch (opcode) {
      case op(Opcode::Schema): { Schema s; parsed = parseSchema(content, s); break; }
      case op(Opcode::Channel): { Channel c; parsed = parseChannel(content, c); break; }
      case op(Opcode::Statistics): { Statistics s; parsed = parseStatistics(content, s); break; }
      case op(Opcode::ChunkIndex): { ChunkIndex c; parsed = parseChunkIndex(content, c); break; }
      case op(Opcode::AttachmentIndex): { AttachmentIndex a; parsed = parseAttachmentIndex(content, a); break; }
      case op(Opcode::MetadataIndex): { MetadataIndex m; parsed = parseMetadataIndex(content, m); break; }
      case op(Opcode::SummaryOffset): { SummaryOffset s; parsed = parseSummaryOffset(content, s); break; }
      default:
        if (opcode >= 0x01 && opcode <= 0x0F)
          damage(p, DamageKind::MisplacedRecord, opcodeName(opcode) + " record in the summary section");
        else ++h_.unknown_records;
    }
    if (!parsed) damage(p, DamageKind::BadSummary, "malformed " + opcodeName(opcode) + " record in the summary");
    p += kRecordPrefix + length;
  }
}

// Spec "Footer": the summary CRC covers from the summary start through the footer's
// summary_offset_start field; then the closing magic ends the file.
void Scanner::handleFooter(std::uint64_t at, std::uint64_t length, std::optional<std::uint64_t> summary_crc_start) {
  if (length < kFooterContent) {
    damage(at, DamageKind::BadFooter, "Footer record of " + num(length) + " bytes (20 expected)");
    return;
  }
  Footer f;
  parseFooter(src_.view(at + kRecordPrefix, kFooterContent), f);
  h_.footer_found = true;
  if (summary_crc_start && f.summary_start != 0 && f.summary_start != *summary_crc_start)
    damage(at, DamageKind::BadFooter,
           "Footer summary_start is " + num(f.summary_start) + " but the summary starts at " + num(*summary_crc_start));
  if (f.summary_offset_start != 0 &&
      (f.summary_offset_start > at || (summary_crc_start && f.summary_offset_start < *summary_crc_start)))
    damage(at, DamageKind::BadFooter, "Footer summary_offset_start " + num(f.summary_offset_start) + " is outside the summary");
  if (summary_crc_start && f.summary_crc != 0) {
    const std::uint32_t computed = crcOver(*summary_crc_start, at + kRecordPrefix + 16);
    if (computed == f.summary_crc) h_.summary_crc_checked = true;
    else
      damage(at, DamageKind::SummaryCrcMismatch,
             "summary CRC mismatch (stored " + num(f.summary_crc) + ", computed " + num(computed) + ")");
  }
  const std::uint64_t magic_at = at + kRecordPrefix + length;
  const Bytes magic = src_.view(magic_at, kMcapMagic.size());
  if (magic.size() < kMcapMagic.size()) {
    const bool prefix = std::equal(magic.begin(), magic.end(), kMcapMagic.begin(),
                                   [](std::byte a, std::uint8_t b) { return std::to_integer<std::uint8_t>(a) == b; });
    if (prefix) truncate("magic", magic_at, kMcapMagic.size(), magic.size());
    else damage(magic_at, DamageKind::BadMagic, "the file does not end with the MCAP magic");
  } else if (!isMagic(magic)) {
    damage(magic_at, DamageKind::BadMagic, "the file does not end with the MCAP magic");
  } else if (magic_at + kMcapMagic.size() < size_) {
    damage(magic_at + kMcapMagic.size(), DamageKind::BadRecord,
           num(size_ - magic_at - kMcapMagic.size()) + " bytes follow the closing magic");
  }
}

// --- recovery -----------------------------------------------------------------------------------

bool Scanner::plausibleRecordAt(std::uint64_t at) {
  if (at == size_) return !trailer_valid_;
  if (trailer_valid_ && at == footer_offset_) return true;
  const Bytes head = src_.view(at, kRecordPrefix);
  if (head.size() < kRecordPrefix) return !trailer_valid_;
  const auto opcode = std::to_integer<std::uint8_t>(head[0]);
  if (opcode == 0) return false;
  return readU64(head.subspan(1, 8)) <= size_ - at - kRecordPrefix || !trailer_valid_;
}

// The record at `bad` cannot be right, so the length that led here may not be either: search again
// from just after the start of the last record taken on an unconfirmed length, or, when a CRC
// confirmed that record, from the end of what the CRC covered (its stated length is not covered).
// Each search starts after the start of the last record handled, so this ends.
void Scanner::lostFraming(std::uint64_t bad, const std::string& what, DamageKind kind) {
  damage(bad, kind, what);
  if (record_vouched_) resync(std::min(bad + 1, vouched_end_));
  else resync(record_start_ < bad ? record_start_ + 1 : bad + 1);
}

std::optional<std::uint64_t> Scanner::findAnchor(std::uint64_t from) {
  std::uint64_t p = from;
  while (p < size_) {
    const Bytes block = src_.view(p, kResyncBlock);
    std::uint64_t candidate = size_;
    for (std::size_t i = 0; i < block.size(); ++i) {
      const auto b = std::to_integer<std::uint8_t>(block[i]);
      if (b == op(Opcode::Chunk) || b == op(Opcode::Attachment) || b == op(Opcode::DataEnd) || b == op(Opcode::Footer)) {
        candidate = p + i;
        break;
      }
    }
    if (candidate == size_) {
      p += block.size();
      continue;
    }
    if (validAnchor(candidate)) return candidate;  // (it used the source: the block is gone)
    p = candidate + 1;
  }
  return std::nullopt;
}

void Scanner::resync(std::uint64_t from) {
  if (const std::optional<std::uint64_t> anchor = findAnchor(from)) {
    damage(from, DamageKind::Resynchronised,
           "skipped " + num(*anchor - from) + " bytes (" + num(from) + ".." + num(*anchor) +
               ") to the next record that validates, a " +
               opcodeName(std::to_integer<std::uint8_t>(src_.view(*anchor, 1)[0])) + " at byte " + num(*anchor));
    pos_ = record_start_ = *anchor;
    vouched_end_ = *anchor + 1;
  } else {
    damage(from, DamageKind::Resynchronised,
           "no record that validates in bytes " + num(from) + ".." + num(size_) + ": the rest of the file is unreadable");
    pos_ = record_start_ = vouched_end_ = size_;
  }
  record_vouched_ = true;
}

// A record that proves itself: a chunk or attachment whose CRC matches, or the Data End and Footer
// where a valid footer puts them.
bool Scanner::validAnchor(std::uint64_t at) {
  if (data_end_offset_ && at == *data_end_offset_) return true;
  if (trailer_valid_ && at == footer_offset_) return true;
  const Bytes head = src_.view(at, kRecordPrefix);
  if (head.size() < kRecordPrefix) return false;
  const auto opcode = std::to_integer<std::uint8_t>(head[0]);
  const std::uint64_t length = readU64(head.subspan(1, 8));
  if (length > size_ - at - kRecordPrefix) return false;
  if (data_end_offset_ && at + kRecordPrefix + length > *data_end_offset_) return false;
  if (opcode == op(Opcode::Chunk)) return chunkValidates(at, length);
  if (opcode == op(Opcode::Attachment)) return checkAttachment(at, length, nullptr) == AttachmentCheck::kOk;
  return false;
}

bool Scanner::chunkValidates(std::uint64_t at, std::uint64_t length) {
  if (length > options_.max_chunk_bytes + (1 << 16)) return false;
  const Bytes content = src_.view(at + kRecordPrefix, static_cast<std::size_t>(length));
  ChunkHeader header;
  if (parseChunkHeader(content, length, header) != ParseResult::kOk || header.uncompressed_crc == 0 ||
      header.message_start_time > header.message_end_time)
    return false;
  const DecodedChunk chunk = decodeChunk(content, header, options_.max_chunk_bytes, buffer_);
  return chunk.ok && chunk.verified;
}

}  // namespace stampscan::trace::detail
