#include "stampscan/acquisition/trace/mcap_writer.hpp"

#include "mcap_codec.hpp"
#include "mcap_compression.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>
#include <vector>

namespace stampscan::trace {

using detail::Bytes;
using detail::RecordBuilder;

struct McapWriter::Impl {
  std::filesystem::path path;
  McapWriterOptions options;
  int fd = -1;
  bool failed = false;            // an I/O error happened: nothing more is written
  std::uint64_t offset = 0;       // bytes written to the file
  std::uint32_t data_crc = 0;     // spec "Data End": CRC of every byte from the file's start
  std::uint32_t summary_crc = 0;  // spec "Footer": CRC from the summary start through the footer's offsets
  bool in_summary = false;

  std::vector<Schema> schemas;
  std::vector<Channel> channels;
  std::vector<std::uint32_t> sequences;  // next sequence number per channel
  Statistics stats;
  std::vector<ChunkIndex> chunk_indexes;
  std::vector<AttachmentIndex> attachment_indexes;
  std::vector<MetadataIndex> metadata_indexes;

  // The open chunk: uncompressed records, and per channel the (log_time, offset) of its messages.
  RecordBuilder chunk;
  std::uint64_t chunk_start_time = 0, chunk_end_time = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_messages;
  detail::ChunkCompressor compressor;
  std::vector<std::byte> compressed;
  RecordBuilder scratch;

  Impl(std::filesystem::path p, McapWriterOptions o)
      : path(std::move(p)), options(std::move(o)), compressor(options.compression, options.compression_level) {}

  [[noreturn]] void fail(const std::string& what) {
    failed = true;
    throw std::runtime_error(path.string() + ": " + what + ": " + std::strerror(errno));
  }

  void check() const {
    if (fd < 0) throw std::logic_error(path.string() + ": trace writer is closed");
    if (failed) throw std::runtime_error(path.string() + ": trace writer stopped after an earlier I/O error");
  }

  // Appends to the file, keeping the CRC of the section being written.
  void emit(Bytes bytes) {
    if (in_summary) summary_crc = detail::crc32(summary_crc, bytes);
    else data_crc = detail::crc32(data_crc, bytes);
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) fail("write failed at byte " + std::to_string(offset + done));
      done += static_cast<std::size_t>(n);
    }
    offset += bytes.size();
  }

  void emitScratch() {
    emit(scratch.bytes());
    scratch.clear();
  }

  void writeChunk();
};

// Spec "Chunk" then one "Message Index" per channel with messages in it; the Chunk Index is kept for
// the summary. Message index offsets are into the uncompressed records (spec "Message Index").
void McapWriter::Impl::writeChunk() {
  if (chunk_messages.empty()) return;
  const Bytes records = chunk.bytes();
  const std::uint32_t crc = detail::crc32(0, records);  // always filled in: the reader's only check of a chunk
  Compression used = options.compression;
  compressor.compress(records, compressed);
  // Incompressible data (already-compressed images) is stored as is rather than grown.
  if (used != Compression::None && compressed.size() >= records.size()) used = Compression::None;
  const Bytes stored = used == Compression::None ? records : Bytes(compressed);
  const std::string compression = compressionName(used);

  ChunkIndex index;
  index.message_start_time = chunk_start_time;
  index.message_end_time = chunk_end_time;
  index.chunk_start_offset = offset;
  index.compression = compression;
  index.compressed_size = stored.size();
  index.uncompressed_size = records.size();

  const std::size_t r = scratch.begin(Opcode::Chunk);
  scratch.u64(chunk_start_time);
  scratch.u64(chunk_end_time);
  scratch.u64(records.size());
  scratch.u32(crc);
  scratch.string(compression);
  scratch.u64(stored.size());
  // The records go straight from their buffer to the file; the length prefix covers them.
  std::vector<std::byte>& head = scratch.bytes();
  std::uint64_t length = head.size() - r - detail::kRecordPrefix + stored.size();
  for (std::size_t i = 0; i < 8; ++i, length >>= 8) head[r + 1 + i] = static_cast<std::byte>(length & 0xFF);
  emitScratch();
  emit(stored);
  index.chunk_length = offset - index.chunk_start_offset;

  const std::uint64_t indexes_start = offset;
  for (const auto& [channel, entries] : chunk_messages) {
    index.message_index_offsets[channel] = offset + scratch.bytes().size();
    detail::appendMessageIndex(scratch, channel, entries);
  }
  emitScratch();
  index.message_index_length = offset - indexes_start;
  chunk_indexes.push_back(std::move(index));
  ++stats.chunk_count;

  chunk.clear();
  chunk_messages.clear();
  if (options.fsync_chunks && ::fsync(fd) != 0) fail("fsync failed");
}

McapWriter::McapWriter(const std::filesystem::path& path, McapWriterOptions options)
    : impl_(std::make_unique<Impl>(path, std::move(options))) {
  if (impl_->options.chunk_size == 0) throw std::invalid_argument("McapWriter: chunk_size must be positive");
  impl_->fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (impl_->fd < 0) impl_->fail("cannot create");
  RecordBuilder& out = impl_->scratch;
  out.raw(Bytes(reinterpret_cast<const std::byte*>(kMcapMagic.data()), kMcapMagic.size()));
  detail::appendHeader(out, Header{impl_->options.profile, impl_->options.library});
  impl_->emitScratch();
}

McapWriter::~McapWriter() {
  try {
    close();
  } catch (...) {  // a destructor must not throw; close() explicitly to see the error
  }
  if (impl_ && impl_->fd >= 0) ::close(impl_->fd);
}

McapWriter::McapWriter(McapWriter&&) noexcept = default;

McapWriter& McapWriter::operator=(McapWriter&& other) noexcept {
  if (this != &other) {
    McapWriter old(std::move(*this));  // closes what this held
    impl_ = std::move(other.impl_);
  }
  return *this;
}

std::uint16_t McapWriter::addSchema(std::string_view name, std::string_view encoding, std::span<const std::byte> data) {
  impl_->check();
  if (impl_->schemas.size() >= std::numeric_limits<std::uint16_t>::max())
    throw std::length_error(impl_->path.string() + ": too many schemas");
  Schema s;
  s.id = static_cast<std::uint16_t>(impl_->schemas.size() + 1);
  s.name = name;
  s.encoding = encoding;
  s.data.assign(data.begin(), data.end());
  detail::appendSchema(impl_->scratch, s);
  impl_->emitScratch();
  impl_->schemas.push_back(std::move(s));
  ++impl_->stats.schema_count;
  return impl_->schemas.back().id;
}

std::uint16_t McapWriter::addSchema(std::string_view name, std::string_view encoding, std::string_view data) {
  return addSchema(name, encoding, detail::asBytes(data));
}

std::uint16_t McapWriter::addChannel(std::uint16_t schema_id, std::string_view topic, std::string_view message_encoding,
                                     const KeyValues& metadata) {
  impl_->check();
  if (schema_id > impl_->schemas.size())
    throw std::invalid_argument(impl_->path.string() + ": channel " + std::string(topic) + ": unknown schema id " +
                                std::to_string(schema_id));
  if (impl_->channels.size() >= std::numeric_limits<std::uint16_t>::max())
    throw std::length_error(impl_->path.string() + ": too many channels");
  Channel c;
  c.id = static_cast<std::uint16_t>(impl_->channels.size() + 1);
  c.schema_id = schema_id;
  c.topic = topic;
  c.message_encoding = message_encoding;
  c.metadata = metadata;
  detail::appendChannel(impl_->scratch, c);
  impl_->emitScratch();
  impl_->channels.push_back(std::move(c));
  impl_->sequences.push_back(0);
  impl_->stats.channel_message_counts[impl_->channels.back().id] = 0;
  ++impl_->stats.channel_count;
  return impl_->channels.back().id;
}

void McapWriter::write(std::uint16_t channel, std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
                       std::span<const std::byte> data) {
  Impl& m = *impl_;
  m.check();
  if (channel == 0 || channel > m.channels.size())
    throw std::invalid_argument(m.path.string() + ": unknown channel id " + std::to_string(channel));
  // A chunk covers at most chunk_duration_ns of log time, so a replay or a time query reads little
  // beyond what it needs; close it before this message would stretch it further.
  if (!m.chunk_messages.empty()) {
    const std::uint64_t start = std::min(m.chunk_start_time, log_time_ns);
    const std::uint64_t end = std::max(m.chunk_end_time, log_time_ns);
    if (end - start > m.options.chunk_duration_ns) m.writeChunk();
  }
  if (m.chunk_messages.empty()) m.chunk_start_time = m.chunk_end_time = log_time_ns;
  const std::uint64_t at = m.chunk.bytes().size();
  detail::appendMessage(m.chunk, channel, m.sequences[channel - 1]++, log_time_ns, publish_time_ns, data);
  m.chunk_messages[channel].emplace_back(log_time_ns, at);
  m.chunk_start_time = std::min(m.chunk_start_time, log_time_ns);
  m.chunk_end_time = std::max(m.chunk_end_time, log_time_ns);

  Statistics& s = m.stats;
  s.message_start_time = s.message_count == 0 ? log_time_ns : std::min(s.message_start_time, log_time_ns);
  s.message_end_time = s.message_count == 0 ? log_time_ns : std::max(s.message_end_time, log_time_ns);
  ++s.message_count;
  ++s.channel_message_counts[channel];
  if (m.chunk.bytes().size() >= m.options.chunk_size) m.writeChunk();
}

void McapWriter::addMetadata(std::string_view name, const KeyValues& metadata) {
  impl_->check();
  MetadataIndex index;
  index.offset = impl_->offset;
  index.name = name;
  detail::appendMetadata(impl_->scratch, name, metadata);
  impl_->emitScratch();
  index.length = impl_->offset - index.offset;
  impl_->metadata_indexes.push_back(std::move(index));
  ++impl_->stats.metadata_count;
}

void McapWriter::addAttachment(std::string_view name, std::string_view media_type, std::uint64_t log_time_ns,
                               std::span<const std::byte> data, std::uint64_t create_time_ns) {
  Impl& m = *impl_;
  m.check();
  // Spec "Attachment": log_time, create_time, name, media_type, data (uint64 length-prefixed), and a
  // CRC of all those fields. Attachments never go inside chunks. The data is written in place.
  AttachmentIndex index;
  index.offset = m.offset;
  index.log_time = log_time_ns;
  index.create_time = create_time_ns;
  index.data_size = data.size();
  index.name = name;
  index.media_type = media_type;
  RecordBuilder& out = m.scratch;
  out.u8(static_cast<std::uint8_t>(Opcode::Attachment));
  out.u64(8 + 8 + 4 + name.size() + 4 + media_type.size() + 8 + data.size() + 4);
  const std::size_t fields = out.bytes().size();
  out.u64(log_time_ns);
  out.u64(create_time_ns);
  out.string(name);
  out.string(media_type);
  out.u64(data.size());
  std::uint32_t crc = detail::crc32(0, Bytes(out.bytes()).subspan(fields));
  crc = detail::crc32(crc, data);
  m.emitScratch();
  m.emit(data);
  out.u32(crc);
  m.emitScratch();
  index.length = m.offset - index.offset;
  m.attachment_indexes.push_back(std::move(index));
  ++m.stats.attachment_count;
}

void McapWriter::flush() {
  impl_->check();
  impl_->writeChunk();
}

void McapWriter::close() {
  if (!impl_ || impl_->fd < 0) return;
  Impl& m = *impl_;
  if (m.failed) {
    ::close(m.fd);
    m.fd = -1;
    return;
  }
  m.writeChunk();
  detail::appendDataEnd(m.scratch, m.data_crc);
  m.emitScratch();

  // Summary section, grouped by opcode (spec "Summary Section"); each group is located by a Summary Offset.
  m.in_summary = true;
  const std::uint64_t summary_start = m.offset;
  std::vector<SummaryOffset> groups;
  const auto group = [&](Opcode opcode, auto&& append) {
    const std::uint64_t start = m.offset;
    append();
    if (!m.scratch.bytes().empty()) {
      m.emitScratch();
      groups.push_back({static_cast<std::uint8_t>(opcode), start, m.offset - start});
    }
  };
  group(Opcode::Schema, [&] { for (const Schema& s : m.schemas) detail::appendSchema(m.scratch, s); });
  group(Opcode::Channel, [&] { for (const Channel& c : m.channels) detail::appendChannel(m.scratch, c); });
  group(Opcode::Statistics, [&] { detail::appendStatistics(m.scratch, m.stats); });
  group(Opcode::ChunkIndex, [&] { for (const ChunkIndex& c : m.chunk_indexes) detail::appendChunkIndex(m.scratch, c); });
  group(Opcode::AttachmentIndex,
        [&] { for (const AttachmentIndex& a : m.attachment_indexes) detail::appendAttachmentIndex(m.scratch, a); });
  group(Opcode::MetadataIndex,
        [&] { for (const MetadataIndex& i : m.metadata_indexes) detail::appendMetadataIndex(m.scratch, i); });
  const std::uint64_t summary_offset_start = m.offset;
  for (const SummaryOffset& g : groups) detail::appendSummaryOffset(m.scratch, g);
  m.emitScratch();

  // Footer: the summary CRC covers everything from the summary start up to and including the footer's
  // summary_offset_start field (opcode and length prefix included), but not the CRC itself.
  RecordBuilder& out = m.scratch;
  out.u8(static_cast<std::uint8_t>(Opcode::Footer));
  out.u64(detail::kFooterContent);
  out.u64(summary_start);
  out.u64(summary_offset_start);
  m.emitScratch();
  out.u32(m.summary_crc);
  out.raw(Bytes(reinterpret_cast<const std::byte*>(kMcapMagic.data()), kMcapMagic.size()));
  m.emitScratch();
  if (m.options.fsync_chunks && ::fsync(m.fd) != 0) m.fail("fsync failed");
  const int fd = m.fd;
  m.fd = -1;
  if (::close(fd) != 0) m.fail("close failed");
}

bool McapWriter::isOpen() const { return impl_ && impl_->fd >= 0 && !impl_->failed; }
const std::filesystem::path& McapWriter::path() const { return impl_->path; }
const Statistics& McapWriter::statistics() const { return impl_->stats; }

}  // namespace stampscan::trace
