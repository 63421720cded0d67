// Decoding a Chunk record's `records` field (spec "Chunk (op=0x06)") and walking the records inside.
#pragma once

#include "mcap_codec.hpp"
#include "stampscan/acquisition/trace/mcap_reader.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace stampscan::trace::detail {

struct DecodedChunk {
  bool ok = false;
  DamageKind kind = DamageKind::ChunkUndecodable;  // when !ok
  std::string what;                                // when !ok
  Bytes records;       // the uncompressed records: into the chunk content (no compression) or `buffer`
  bool verified = false;  // the chunk carried a CRC and it matched
};

// Decodes a whole chunk: the compression must be known, the decoded size must equal
// uncompressed_size (at most max_bytes) and a non-zero CRC must match.
DecodedChunk decodeChunk(Bytes content, const ChunkHeader& header, std::uint64_t max_bytes,
                         std::vector<std::byte>& buffer);

// Decodes as much as `present` (the records bytes a cut file holds) yields; nothing is verified.
Bytes decodeCutChunk(Bytes present, const ChunkHeader& header, std::uint64_t max_bytes, std::vector<std::byte>& buffer);

// Calls `visit(opcode, content, offset_in_records)` for each complete record; stops early when
// visit returns false. Returns the offset where walking stopped: records.size() when every record
// was complete, less when the last one is cut (or the walk was stopped).
std::size_t forEachRecord(Bytes records, const std::function<bool(std::uint8_t, Bytes, std::size_t)>& visit);

}  // namespace stampscan::trace::detail
