// McapReader: reads MCAP traces (https://mcap.dev/spec), ours and other tools' (messages in or out of
// chunks, schemas and channels in or out of chunks, zstd / lz4 / no compression), and recovers what
// it can from damaged or cut files.
//
// Two ways in:
//  - summary(): the footer and summary section (schemas, channels, statistics, chunk, attachment
//    and metadata indexes), when present and their CRC checks; readChunk() then reads one chunk
//    through its message index.
//  - readMessages(): a linear scan of the whole file from the start, delivering every message in file
//    order. It checks every chunk CRC, attachment CRC, the data section CRC and the summary CRC, and
//    never throws or crashes on damaged content: what it found wrong, and where, is in the returned
//    TraceHealth. A file cut at any byte yields every complete message before the cut (zstd and lz4
//    chunks are decoded as far as their bytes go).
//
// Files may be many GB: bytes are read with positional reads through a window, never all at once.
// A reader is not thread-safe; open one per thread.
#pragma once

#include "stampscan/acquisition/trace/mcap_records.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

namespace stampscan::trace {

// One message. `data` (and `channel`) are valid only during the callback.
struct TraceMessage {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;
  std::uint64_t publish_time = 0;
  std::span<const std::byte> data;
  const Channel* channel = nullptr;  // its Channel record, when one was found
  std::uint64_t record_offset = 0;   // file offset of the enclosing Chunk record, or of the Message record
  // True when a CRC vouches for these bytes: the message came from a chunk whose CRC matched. False
  // for messages outside chunks, in chunks without a CRC, or decoded from a chunk cut by the end of
  // the file.
  bool verified = false;
};

// Returns false to stop reading.
using MessageCallback = std::function<bool(const TraceMessage&)>;

struct ReadOptions {
  std::set<std::uint16_t> channels;  // only these channel ids (empty: all)
  std::set<std::string> topics;      // only channels with these topics (empty: all)
  std::uint64_t start_time = 0;      // log time range, both ends included
  std::uint64_t end_time = std::numeric_limits<std::uint64_t>::max();
  // Chunks declaring more uncompressed bytes than this are reported, not decoded (a damaged size
  // field must not allocate terabytes).
  std::uint64_t max_chunk_bytes = std::uint64_t{4} << 30;
};

enum class DamageKind {
  BadMagic,            // the file does not start or end with the MCAP magic
  BadRecord,           // a record whose fields do not fit its length, or an invalid value
  BadLength,           // a record length that runs past the end of the file or its section
  MisplacedRecord,     // a record where the spec does not allow it (e.g. an index in the data section)
  Resynchronised,      // bytes skipped to find the next record that validates
  ChunkCrcMismatch,    // the chunk's messages were not delivered
  ChunkUndecodable,    // unknown compression, decompression error or size mismatch: not delivered
  AttachmentCrcMismatch,
  DataSectionCrcMismatch,
  MissingDataEnd,
  SummaryCrcMismatch,
  BadFooter,
  BadSummary,
  UnknownChannel,      // messages on a channel id no Channel record defines
};
std::string toString(DamageKind kind);

struct Damage {
  std::uint64_t offset = 0;  // file offset of the damaged record or byte range
  DamageKind kind = DamageKind::BadRecord;
  std::string what;          // one line: what was wrong and what it cost
};

// Where and how the file ends early.
struct Truncation {
  std::uint64_t file_size = 0;      // the file ends here
  std::string record;               // what was cut: a record name ("Chunk"), "magic", "record header", ...
  std::uint64_t record_offset = 0;  // where that record starts
  std::uint64_t bytes_needed = 0;   // its full length
  std::uint64_t bytes_present = 0;  // how much of it the file holds
};

struct AttachmentInfo {
  std::uint64_t offset = 0;
  std::string name, media_type;
  std::uint64_t log_time = 0, create_time = 0, data_size = 0;
  bool crc_checked = false;  // the record carried a CRC and it matched
};

struct MetadataInfo {
  std::uint64_t offset = 0;
  std::string name;
  KeyValues metadata;
};

// What a linear scan found, and what was wrong with the file.
struct TraceHealth {
  std::uint64_t file_size = 0;
  bool not_mcap = false;  // neither the MCAP magic nor a Header at the start: some other kind of file
  std::optional<Header> header;
  std::optional<Truncation> truncated;
  std::vector<Damage> damage;
  bool stopped = false;            // the callback stopped the scan: the rest was not checked
  bool data_end_found = false;
  bool data_crc_checked = false;   // Data End held a CRC and it matched
  bool footer_found = false;
  bool summary_crc_checked = false;  // the footer held a summary CRC and it matched

  // Contents seen in the data section.
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::vector<AttachmentInfo> attachments;
  std::vector<MetadataInfo> metadata;
  std::uint64_t chunks = 0;              // chunks decoded and delivered
  std::uint64_t chunks_damaged = 0;      // chunks whose messages were not delivered
  std::uint64_t chunk_compressed_bytes = 0, chunk_uncompressed_bytes = 0;  // over decoded whole chunks
  std::set<std::string> compressions;    // compression names seen ("" = none)
  std::uint64_t messages_found = 0;      // messages recovered, before the filters
  std::uint64_t messages_delivered = 0;  // messages passed to the callback
  std::uint64_t messages_unverified = 0; // of messages_found, those no CRC vouches for
  std::uint64_t messages_lost = 0;       // messages of damaged chunks, counted from their message indexes
  std::uint64_t unknown_records = 0;     // records with opcodes this reader does not know, skipped

  // The whole file was read and nothing was wrong with it.
  bool healthy() const {
    return !not_mcap && !stopped && !truncated && damage.empty() && data_end_found && footer_found;
  }
};

// What a damaged or cut trace cost in recorded data, in one line ("412 messages in 2 damaged chunks
// (bytes 1048576, 3145728); the trace is cut at byte 5000000, before its data section ends"), or
// nothing when every recorded message was read: damage confined to the summary, or a cut after the
// data section, loses no data. Commands refuse to report a result from a trace that lost data
// unless told to accept it.
std::optional<std::string> describeDataLoss(const TraceHealth& health);

struct Summary {
  Header header;
  Footer footer;
  std::uint64_t footer_offset = 0;
  std::uint64_t data_end_offset = 0;
  std::uint32_t data_section_crc = 0;  // as stored in Data End (checked only by readMessages)
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::optional<Statistics> statistics;
  std::vector<ChunkIndex> chunk_indexes;
  std::vector<AttachmentIndex> attachment_indexes;
  std::vector<MetadataIndex> metadata_indexes;
  std::vector<SummaryOffset> summary_offsets;
};

class McapReader {
 public:
  // Opens a file. Throws std::runtime_error naming the path when it cannot be opened; whatever is
  // in it, valid or not, is reported by the functions below instead.
  explicit McapReader(const std::filesystem::path& path);
  // Reads bytes held in memory, which must outlive the reader; `name` is used in messages.
  McapReader(std::span<const std::byte> bytes, std::string name);
  ~McapReader();
  McapReader(McapReader&&) noexcept;
  McapReader& operator=(McapReader&&) noexcept;

  const std::string& name() const;
  std::uint64_t fileSize() const;

  // The summary, or nullopt when the file has none usable (no footer, no summary section, a CRC or
  // parse failure); the reasons go to `problems` when given.
  std::optional<Summary> summary(std::vector<Damage>* problems = nullptr);

  // The linear, recovering scan described above. With a null callback it only checks the file.
  // Throws only on I/O errors (std::runtime_error naming the file) or what the callback throws.
  TraceHealth readMessages(const MessageCallback& callback, const ReadOptions& options = {});
  TraceHealth check() { return readMessages(nullptr); }

  // Reads one chunk through its index (random access, e.g. to a time): checks its CRC and delivers
  // its messages in log-time order as its Message Index records list them, checking each entry
  // against the message at its offset. `options` filters as in readMessages. Returns false, with
  // the reasons in `problems`, when the chunk or its index is damaged; then nothing was delivered
  // unless the damage is in an index entry, found only after the entries before it.
  bool readChunk(const ChunkIndex& index, const std::map<std::uint16_t, Channel>& channels,
                 const MessageCallback& callback, std::vector<Damage>* problems = nullptr,
                 const ReadOptions& options = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::trace
