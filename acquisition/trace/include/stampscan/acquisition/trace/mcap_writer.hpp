// McapWriter: records a trace as an MCAP file (https://mcap.dev/spec), one channel per device stream.
//
// Layout written (spec "File Structure"): Magic, Header, then the data section as data arrives:
// Schema and Channel records as they are added (outside chunks, so a cut file still knows them),
// Chunks of Message records each followed by its Message Index records, Metadata and Attachments;
// on close(): Data End with the CRC of everything before it, the summary section (Schemas,
// Channels, Statistics, Chunk Indexes, Attachment Indexes, Metadata Indexes), the Summary Offset
// section, the Footer with the summary CRC, and the closing Magic.
//
// Nothing recorded is lost (ARCHITECTURE.md): the file is only appended to, every record outside a
// chunk is handed to the kernel at once and each chunk as soon as it closes (optionally fsync'ed),
// so a crash loses at most the open chunk; McapReader recovers the rest.
//
// Not thread-safe: one thread writes (acquisition funnels device data through one recorder).
#pragma once

#include "stampscan/acquisition/trace/mcap_records.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace stampscan::trace {

struct McapWriterOptions {
  std::string profile = "x-stampscan";  // spec Header.profile; custom profiles take the "x-" prefix
  std::string library = "stampscan 0.1";
  Compression compression = Compression::Zstd;
  // zstd level 1 keeps up with camera streams on one core; lz4 level 0 is its fast mode.
  int compression_level = 1;
  std::uint64_t chunk_size = std::uint64_t{1} << 20;     // close a chunk at this many uncompressed bytes
  std::uint64_t chunk_duration_ns = 1'000'000'000;       // ... or when its messages span this much log time
  bool fsync_chunks = false;                             // fsync after each chunk: survives power loss too
};

class McapWriter {
 public:
  // Creates (truncates) `path` and writes the magic and the Header. Throws std::runtime_error naming
  // the path when it cannot.
  explicit McapWriter(const std::filesystem::path& path, McapWriterOptions options = {});
  // Closes the file if close() was not called; errors are swallowed here, so call close() to see them.
  ~McapWriter();
  McapWriter(McapWriter&&) noexcept;
  McapWriter& operator=(McapWriter&&) noexcept;

  // Ids are assigned from 1 in call order. The record is written to the file before returning.
  std::uint16_t addSchema(std::string_view name, std::string_view encoding, std::span<const std::byte> data);
  std::uint16_t addSchema(std::string_view name, std::string_view encoding, std::string_view data);
  // schema_id 0: no schema. Throws std::invalid_argument for an unknown schema id.
  std::uint16_t addChannel(std::uint16_t schema_id, std::string_view topic, std::string_view message_encoding,
                           const KeyValues& metadata = {});

  // One message; its sequence number is the count of earlier messages on the channel. Throws
  // std::invalid_argument for an unknown channel, std::runtime_error on I/O failure.
  void write(std::uint16_t channel, std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
             std::span<const std::byte> data);
  void addMetadata(std::string_view name, const KeyValues& metadata);
  void addAttachment(std::string_view name, std::string_view media_type, std::uint64_t log_time_ns,
                     std::span<const std::byte> data, std::uint64_t create_time_ns = 0);

  // Writes the open chunk now (e.g. at the end of a scan step) instead of when it fills.
  void flush();
  // Writes the open chunk, Data End, the summary and the footer, and closes the file. Idempotent.
  void close();

  bool isOpen() const;
  const std::filesystem::path& path() const;
  const Statistics& statistics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::trace
