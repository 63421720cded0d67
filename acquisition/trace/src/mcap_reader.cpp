#include "stampscan/acquisition/trace/mcap_reader.hpp"

#include "byte_source.hpp"
#include "mcap_chunk.hpp"
#include "mcap_codec.hpp"
#include "mcap_scan.hpp"

#include <algorithm>
#include <tuple>

namespace stampscan::trace {

using namespace detail;

std::string toString(DamageKind kind) {
  switch (kind) {
    case DamageKind::BadMagic: return "bad magic";
    case DamageKind::BadRecord: return "bad record";
    case DamageKind::BadLength: return "bad length";
    case DamageKind::MisplacedRecord: return "misplaced record";
    case DamageKind::Resynchronised: return "resynchronised";
    case DamageKind::ChunkCrcMismatch: return "chunk CRC mismatch";
    case DamageKind::ChunkUndecodable: return "chunk undecodable";
    case DamageKind::AttachmentCrcMismatch: return "attachment CRC mismatch";
    case DamageKind::DataSectionCrcMismatch: return "data section CRC mismatch";
    case DamageKind::MissingDataEnd: return "missing Data End";
    case DamageKind::SummaryCrcMismatch: return "summary CRC mismatch";
    case DamageKind::BadFooter: return "bad footer";
    case DamageKind::BadSummary: return "bad summary";
    case DamageKind::UnknownChannel: return "unknown channel";
  }
  return "damage";
}

std::optional<std::string> describeDataLoss(const TraceHealth& health) {
  std::vector<std::string> parts;
  std::string at;
  std::size_t data_damage = 0;
  for (const Damage& d : health.damage) {
    switch (d.kind) {
      // Damage to the summary, the footer or an attachment's CRC costs no recorded message.
      case DamageKind::SummaryCrcMismatch:
      case DamageKind::BadFooter:
      case DamageKind::BadSummary:
      case DamageKind::AttachmentCrcMismatch:
      case DamageKind::MissingDataEnd:
      case DamageKind::DataSectionCrcMismatch:
        continue;
      default:
        break;
    }
    if (++data_damage <= 4) at += (at.empty() ? "" : ", ") + std::to_string(d.offset);
  }
  if (data_damage > 4) at += ", ...";
  if (health.messages_lost > 0 || health.chunks_damaged > 0 || data_damage > 0) {
    std::string text;
    if (health.messages_lost > 0) text = std::to_string(health.messages_lost) + " messages";
    else text = "an unknown number of messages";
    if (health.chunks_damaged > 0) text += " in " + std::to_string(health.chunks_damaged) + " damaged chunks";
    text += " lost (damage at byte" + std::string(data_damage > 1 ? "s " : " ") + at + ")";
    parts.push_back(text);
  }
  if (health.not_mcap) parts.push_back("the file is not an MCAP trace");
  if (health.truncated && !health.data_end_found) {
    parts.push_back("the trace is cut at byte " + std::to_string(health.truncated->file_size) +
                    ", before its data section ends: whatever was recorded after the cut is missing");
  }
  if (parts.empty()) return std::nullopt;
  std::string line = parts.front();
  for (std::size_t i = 1; i < parts.size(); ++i) line += "; " + parts[i];
  return line;
}

struct McapReader::Impl {
  explicit Impl(const std::filesystem::path& path) : source(path) {}
  Impl(std::span<const std::byte> bytes, std::string name) : source(bytes, std::move(name)) {}
  ByteSource source;
  std::vector<std::byte> chunk_buffer, records_copy;
};

McapReader::McapReader(const std::filesystem::path& path) : impl_(std::make_unique<Impl>(path)) {}
McapReader::McapReader(std::span<const std::byte> bytes, std::string name)
    : impl_(std::make_unique<Impl>(bytes, std::move(name))) {}
McapReader::~McapReader() = default;
McapReader::McapReader(McapReader&&) noexcept = default;
McapReader& McapReader::operator=(McapReader&&) noexcept = default;

const std::string& McapReader::name() const { return impl_->source.name(); }
std::uint64_t McapReader::fileSize() const { return impl_->source.size(); }

TraceHealth McapReader::readMessages(const MessageCallback& callback, const ReadOptions& options) {
  TraceHealth health;
  // The summary's channels name the messages of chunks whose Channel record was damaged.
  const std::optional<Summary> s = summary();
  Scanner scanner(impl_->source, callback, options, s ? &s->channels : nullptr, health);
  scanner.run();
  return health;
}

// Spec "Footer" and "Summary Section": read from the end of the file, the way an indexed reader
// starts; nothing here trusts the data section.
std::optional<Summary> McapReader::summary(std::vector<Damage>* problems) {
  ByteSource& src = impl_->source;
  const std::uint64_t size = src.size();
  const auto fail = [&](std::uint64_t offset, DamageKind kind, std::string what) -> std::optional<Summary> {
    if (problems) problems->push_back({offset, kind, std::move(what)});
    return std::nullopt;
  };
  constexpr std::uint64_t kSmallestHeader = kRecordPrefix + 8;
  if (size < kMcapMagic.size() + kSmallestHeader + kDataEndRecord + kFooterAndMagic)
    return fail(0, DamageKind::BadFooter, "file of " + std::to_string(size) + " bytes is too small to hold a summary");
  Summary s;
  if (!isMagic(src.view(0, kMcapMagic.size())))
    return fail(0, DamageKind::BadMagic, "the file does not start with the MCAP magic");
  {
    const Bytes head = src.view(kMcapMagic.size(), kRecordPrefix);
    const std::uint64_t length = readU64(head.subspan(1, 8));
    if (std::to_integer<std::uint8_t>(head[0]) != static_cast<std::uint8_t>(Opcode::Header) ||
        length > size - kMcapMagic.size() - kRecordPrefix - kFooterAndMagic ||
        !parseHeader(src.view(kMcapMagic.size() + kRecordPrefix, static_cast<std::size_t>(length)), s.header))
      return fail(kMcapMagic.size(), DamageKind::BadRecord, "no valid Header record after the magic");
  }
  s.footer_offset = size - kFooterAndMagic;
  const Bytes tail = src.view(s.footer_offset, kFooterAndMagic);
  if (!isMagic(tail.subspan(kFooterAndMagic - kMcapMagic.size())))
    return fail(size - kMcapMagic.size(), DamageKind::BadMagic,
                "the file does not end with the MCAP magic (cut short, or still being written)");
  if (std::to_integer<std::uint8_t>(tail[0]) != static_cast<std::uint8_t>(Opcode::Footer) ||
      readU64(tail.subspan(1, 8)) != kFooterContent)
    return fail(s.footer_offset, DamageKind::BadFooter, "no Footer record before the closing magic");
  parseFooter(tail.subspan(kRecordPrefix, kFooterContent), s.footer);
  const Footer& f = s.footer;
  if (f.summary_start == 0) return fail(s.footer_offset, DamageKind::BadSummary, "the file has no summary section");
  if (f.summary_start < kMcapMagic.size() + kSmallestHeader + kDataEndRecord || f.summary_start > s.footer_offset)
    return fail(s.footer_offset, DamageKind::BadFooter,
                "Footer summary_start " + std::to_string(f.summary_start) + " is outside the file");
  if (s.footer_offset - f.summary_start > (std::uint64_t{1} << 30))
    return fail(f.summary_start, DamageKind::BadSummary, "summary section larger than 1 GiB");

  Bytes view = src.view(f.summary_start, static_cast<std::size_t>(s.footer_offset - f.summary_start));
  std::vector<std::byte> bytes(view.begin(), view.end());
  if (f.summary_crc != 0) {
    // Spec "Footer": summary_crc covers the summary through the footer's summary_offset_start field.
    const std::uint32_t crc = crc32(crc32(0, bytes), src.view(s.footer_offset, kRecordPrefix + 16));
    if (crc != f.summary_crc)
      return fail(s.footer_offset, DamageKind::SummaryCrcMismatch,
                  "summary CRC mismatch (stored " + std::to_string(f.summary_crc) + ", computed " + std::to_string(crc) + ")");
  }
  s.data_end_offset = f.summary_start - kDataEndRecord;
  const Bytes data_end = src.view(s.data_end_offset, kDataEndRecord);
  if (std::to_integer<std::uint8_t>(data_end[0]) != static_cast<std::uint8_t>(Opcode::DataEnd) ||
      readU64(data_end.subspan(1, 8)) != 4)
    return fail(s.data_end_offset, DamageKind::BadSummary, "no Data End record right before the summary");
  s.data_section_crc = readU32(data_end.subspan(kRecordPrefix, 4));

  std::string bad;
  std::uint64_t bad_at = 0;
  const std::size_t end = forEachRecord(bytes, [&](std::uint8_t opcode, Bytes content, std::size_t at) {
    bool ok = true;
    switch (static_cast<Opcode>(opcode)) {
      case Opcode::Schema: {
        Schema schema;
        ok = parseSchema(content, schema);
        if (ok && schema.id != 0) s.schemas[schema.id] = std::move(schema);
        break;
      }
      case Opcode::Channel: {
        Channel channel;
        ok = parseChannel(content, channel);
        if (ok) s.channels[channel.id] = std::move(channel);
        break;
      }
      case Opcode::Statistics:
        ok = !s.statistics && parseStatistics(content, s.statistics.emplace());
        break;
      case Opcode::ChunkIndex: ok = parseChunkIndex(content, s.chunk_indexes.emplace_back()); break;
      case Opcode::AttachmentIndex: ok = parseAttachmentIndex(content, s.attachment_indexes.emplace_back()); break;
      case Opcode::MetadataIndex: ok = parseMetadataIndex(content, s.metadata_indexes.emplace_back()); break;
      case Opcode::SummaryOffset: ok = parseSummaryOffset(content, s.summary_offsets.emplace_back()); break;
      default: ok = opcode > 0x0F;  // application records are skipped; other MCAP records do not belong here
    }
    if (!ok) {
      bad = "bad or misplaced " + opcodeName(opcode) + " record in the summary";
      bad_at = f.summary_start + at;
    }
    return ok;
  });
  if (!bad.empty()) return fail(bad_at, DamageKind::BadSummary, bad);
  if (end != bytes.size())
    return fail(f.summary_start + end, DamageKind::BadSummary, "the summary ends in a partial record");
  return s;
}

bool McapReader::readChunk(const ChunkIndex& index, const std::map<std::uint16_t, Channel>& channels,
                           const MessageCallback& callback, std::vector<Damage>* problems,
                           const ReadOptions& options) {
  ByteSource& src = impl_->source;
  const std::uint64_t at = index.chunk_start_offset;
  const auto fail = [&](std::uint64_t offset, DamageKind kind, std::string what) {
    if (problems) problems->push_back({offset, kind, std::move(what)});
    return false;
  };
  const Bytes head = src.view(at, kRecordPrefix);
  if (index.chunk_length < kRecordPrefix || index.chunk_length > src.size() - std::min(at, src.size()) ||
      head.size() < kRecordPrefix || std::to_integer<std::uint8_t>(head[0]) != static_cast<std::uint8_t>(Opcode::Chunk) ||
      readU64(head.subspan(1, 8)) != index.chunk_length - kRecordPrefix)
    return fail(at, DamageKind::BadRecord, "no Chunk record of the indexed length at byte " + std::to_string(at));
  const std::uint64_t length = index.chunk_length - kRecordPrefix;
  const Bytes content = src.view(at + kRecordPrefix, static_cast<std::size_t>(length));
  ChunkHeader header;
  if (parseChunkHeader(content, length, header) != ParseResult::kOk)
    return fail(at, DamageKind::BadRecord, "malformed Chunk record");
  const DecodedChunk chunk = decodeChunk(content, header, options.max_chunk_bytes, impl_->chunk_buffer);
  if (!chunk.ok) return fail(at, chunk.kind, chunk.what);
  // Reading the message indexes moves the source's window, so keep the records apart from it.
  Bytes records = chunk.records;
  if (records.data() != impl_->chunk_buffer.data()) {
    impl_->records_copy.assign(records.begin(), records.end());
    records = impl_->records_copy;
  }

  // Spec "Message Index": one record per channel right after the chunk; entries are (log_time,
  // offset of the Message record in the uncompressed records).
  std::vector<std::tuple<std::uint64_t, std::uint64_t, std::uint16_t>> entries;
  const std::uint64_t indexes_at = at + index.chunk_length;
  if (index.message_index_length > src.size() - indexes_at)
    return fail(indexes_at, DamageKind::BadLength, "message indexes run past the end of the file");
  const Bytes indexes = src.view(indexes_at, static_cast<std::size_t>(index.message_index_length));
  if (indexes.size() != index.message_index_length)
    return fail(indexes_at, DamageKind::BadLength, "message indexes run past the end of the file");
  std::string bad;
  const std::size_t end = forEachRecord(indexes, [&](std::uint8_t opcode, Bytes body, std::size_t offset) {
    std::uint16_t channel = 0;
    std::vector<std::pair<std::uint64_t, std::uint64_t>> list;
    if (opcode != static_cast<std::uint8_t>(Opcode::MessageIndex) || !parseMessageIndex(body, channel, list)) {
      bad = "malformed Message Index record at byte " + std::to_string(indexes_at + offset);
      return false;
    }
    const auto listed = index.message_index_offsets.find(channel);
    if (!index.message_index_offsets.empty() &&
        (listed == index.message_index_offsets.end() || listed->second != indexes_at + offset)) {
      bad = "the chunk index does not list the Message Index of channel " + std::to_string(channel) + " at byte " +
            std::to_string(indexes_at + offset);
      return false;
    }
    for (const auto& [time, where] : list) entries.emplace_back(time, where, channel);
    return true;
  });
  if (!bad.empty() || end != indexes.size())
    return fail(indexes_at, DamageKind::BadRecord, bad.empty() ? "message indexes end in a partial record" : bad);
  std::stable_sort(entries.begin(), entries.end());

  for (const auto& [time, where, channel_id] : entries) {
    MessageView m;
    const bool found = records.size() >= kRecordPrefix && where <= records.size() - kRecordPrefix &&
                       std::to_integer<std::uint8_t>(records[where]) == static_cast<std::uint8_t>(Opcode::Message) &&
                       readU64(records.subspan(where + 1, 8)) <= records.size() - where - kRecordPrefix &&
                       parseMessage(records.subspan(where + kRecordPrefix, readU64(records.subspan(where + 1, 8))), m);
    if (!found || m.channel_id != channel_id || m.log_time != time)
      return fail(at, DamageKind::BadRecord,
                  "message index entry (channel " + std::to_string(channel_id) + ", log time " + std::to_string(time) +
                      ", offset " + std::to_string(where) + ") does not point at that message");
    const auto c = channels.find(m.channel_id);
    const Channel* channel = c == channels.end() ? nullptr : &c->second;
    if (!callback || (!options.channels.empty() && !options.channels.count(m.channel_id)) ||
        (!options.topics.empty() && (!channel || !options.topics.count(channel->topic))) ||
        m.log_time < options.start_time || m.log_time > options.end_time)
      continue;
    TraceMessage t;
    t.channel_id = m.channel_id;
    t.sequence = m.sequence;
    t.log_time = m.log_time;
    t.publish_time = m.publish_time;
    t.data = m.data;
    t.channel = channel;
    t.record_offset = at;
    t.verified = chunk.verified;
    if (!callback(t)) break;
  }
  return true;
}

}  // namespace stampscan::trace
