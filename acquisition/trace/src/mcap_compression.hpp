// Chunk compression (spec "Chunk": compression "zstd", "lz4" = the LZ4 frame format, or "" = none).
// Decompression is streaming so that a chunk cut short by the end of a file still yields the records
// decoded from the bytes that are there.
#pragma once

#include "stampscan/acquisition/trace/mcap_records.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::trace::detail {

std::optional<Compression> parseCompression(std::string_view name);

class ChunkCompressor {
 public:
  ChunkCompressor(Compression compression, int level);
  ~ChunkCompressor();
  ChunkCompressor(const ChunkCompressor&) = delete;
  ChunkCompressor& operator=(const ChunkCompressor&) = delete;

  // Replaces `out` with the compressed `in`. Throws std::runtime_error if the library fails.
  void compress(std::span<const std::byte> in, std::vector<std::byte>& out);

 private:
  struct State;
  Compression compression_;
  int level_;
  std::unique_ptr<State> state_;
};

class StreamDecompressor {
 public:
  explicit StreamDecompressor(Compression compression);
  ~StreamDecompressor();
  StreamDecompressor(const StreamDecompressor&) = delete;
  StreamDecompressor& operator=(const StreamDecompressor&) = delete;

  enum class Status { kOk, kError, kTooLarge };
  // Decodes all of `in`, appending to `out`, which never grows past max_size + 1 bytes (kTooLarge
  // when more was coming). On kError, `error` holds the library's reason and `out` keeps only what
  // was decoded before the failing call.
  Status feed(std::span<const std::byte> in, std::vector<std::byte>& out, std::uint64_t max_size, std::string& error);
  // True when the input fed so far ended exactly at the end of a compressed frame.
  bool frameComplete() const { return frame_complete_; }

 private:
  struct State;
  Compression compression_;
  std::unique_ptr<State> state_;
  bool frame_complete_ = true;
};

}  // namespace stampscan::trace::detail
