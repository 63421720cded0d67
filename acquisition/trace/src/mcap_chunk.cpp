#include "mcap_chunk.hpp"

#include "mcap_compression.hpp"

#include <algorithm>
#include <optional>

namespace stampscan::trace::detail {

DecodedChunk decodeChunk(Bytes content, const ChunkHeader& header, std::uint64_t max_bytes,
                         std::vector<std::byte>& buffer) {
  DecodedChunk d;
  const Bytes stored = content.subspan(header.records_offset, static_cast<std::size_t>(header.records_size));
  const std::optional<Compression> compression = parseCompression(header.compression);
  if (!compression) {
    d.what = "unknown chunk compression '" + header.compression + "'";
    return d;
  }
  if (header.uncompressed_size > max_bytes) {
    d.what = "chunk declares " + std::to_string(header.uncompressed_size) + " uncompressed bytes, more than the " +
             std::to_string(max_bytes) + " accepted";
    return d;
  }
  if (*compression == Compression::None) {
    if (stored.size() != header.uncompressed_size) {
      d.what = "uncompressed chunk holds " + std::to_string(stored.size()) + " bytes but declares " +
               std::to_string(header.uncompressed_size);
      return d;
    }
    d.records = stored;
  } else {
    buffer.clear();
    // Reserve no more than a sane amount up front: the declared size is not trusted yet, and the
    // decoder grows the buffer as output actually comes.
    buffer.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(header.uncompressed_size, std::uint64_t{64} << 20)));
    StreamDecompressor decoder(*compression);
    std::string error;
    const auto status = decoder.feed(stored, buffer, header.uncompressed_size, error);
    if (status == StreamDecompressor::Status::kError) {
      d.what = header.compression + " decoding failed: " + error;
      return d;
    }
    if (status == StreamDecompressor::Status::kTooLarge || buffer.size() != header.uncompressed_size ||
        !decoder.frameComplete()) {
      d.what = header.compression + " data decodes to " + (status == StreamDecompressor::Status::kTooLarge ? "more than " : "") +
               std::to_string(buffer.size()) + " bytes" + (decoder.frameComplete() ? "" : " in an unfinished frame") +
               ", but the chunk declares " + std::to_string(header.uncompressed_size);
      return d;
    }
    d.records = buffer;
  }
  if (header.uncompressed_crc != 0) {
    const std::uint32_t crc = crc32(0, d.records);
    if (crc != header.uncompressed_crc) {
      d.kind = DamageKind::ChunkCrcMismatch;
      d.what = "chunk CRC mismatch (stored " + std::to_string(header.uncompressed_crc) + ", computed " +
               std::to_string(crc) + ")";
      return d;
    }
    d.verified = true;
  }
  d.ok = true;
  return d;
}

Bytes decodeCutChunk(Bytes present, const ChunkHeader& header, std::uint64_t max_bytes, std::vector<std::byte>& buffer) {
  const std::optional<Compression> compression = parseCompression(header.compression);
  if (!compression) return {};
  if (*compression == Compression::None) return present;
  buffer.clear();
  StreamDecompressor decoder(*compression);
  std::string error;
  // An incomplete frame is expected here; on an error, what decoded before it is still good.
  const std::uint64_t limit = std::min(header.uncompressed_size, max_bytes);
  decoder.feed(present, buffer, limit, error);
  if (buffer.size() > limit) buffer.resize(static_cast<std::size_t>(limit));
  return buffer;
}

std::size_t forEachRecord(Bytes records, const std::function<bool(std::uint8_t, Bytes, std::size_t)>& visit) {
  std::size_t at = 0;
  while (records.size() - at >= kRecordPrefix) {
    const std::uint64_t length = readU64(records.subspan(at + 1, 8));
    if (length > records.size() - at - kRecordPrefix) break;
    const auto n = static_cast<std::size_t>(length);
    if (!visit(std::to_integer<std::uint8_t>(records[at]), records.subspan(at + kRecordPrefix, n), at)) return at;
    at += kRecordPrefix + n;
  }
  return at;
}

}  // namespace stampscan::trace::detail
