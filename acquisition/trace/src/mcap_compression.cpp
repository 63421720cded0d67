#include "mcap_compression.hpp"

#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <stdexcept>

namespace stampscan::trace::detail {

std::optional<Compression> parseCompression(std::string_view name) {
  if (name.empty()) return Compression::None;
  if (name == "zstd") return Compression::Zstd;
  if (name == "lz4") return Compression::Lz4;
  return std::nullopt;
}

// --- compression --------------------------------------------------------------------------------

struct ChunkCompressor::State {
  ZSTD_CCtx* zstd = nullptr;  // reused across chunks: creating a context costs more than a small chunk
  ~State() { ZSTD_freeCCtx(zstd); }
};

ChunkCompressor::ChunkCompressor(Compression compression, int level)
    : compression_(compression), level_(level), state_(std::make_unique<State>()) {
  if (compression_ == Compression::Zstd) {
    state_->zstd = ZSTD_createCCtx();
    if (!state_->zstd) throw std::runtime_error("zstd: cannot create a compression context");
    ZSTD_CCtx_setParameter(state_->zstd, ZSTD_c_compressionLevel, level_);
    // The frame records its content size, so a reader can size its buffer before decoding.
    ZSTD_CCtx_setParameter(state_->zstd, ZSTD_c_contentSizeFlag, 1);
  }
}

ChunkCompressor::~ChunkCompressor() = default;

void ChunkCompressor::compress(std::span<const std::byte> in, std::vector<std::byte>& out) {
  switch (compression_) {
    case Compression::None:
      out.assign(in.begin(), in.end());
      return;
    case Compression::Zstd: {
      out.resize(ZSTD_compressBound(in.size()));
      const std::size_t n = ZSTD_compress2(state_->zstd, out.data(), out.size(), in.data(), in.size());
      if (ZSTD_isError(n)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(n));
      out.resize(n);
      return;
    }
    case Compression::Lz4: {
      LZ4F_preferences_t prefs{};
      prefs.compressionLevel = level_;
      prefs.frameInfo.contentSize = in.size();
      out.resize(LZ4F_compressFrameBound(in.size(), &prefs));
      const std::size_t n = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), &prefs);
      if (LZ4F_isError(n)) throw std::runtime_error(std::string("lz4: ") + LZ4F_getErrorName(n));
      out.resize(n);
      return;
    }
  }
}

// --- decompression ------------------------------------------------------------------------------

struct StreamDecompressor::State {
  ZSTD_DStream* zstd = nullptr;
  LZ4F_dctx* lz4 = nullptr;
  ~State() {
    ZSTD_freeDStream(zstd);
    if (lz4) LZ4F_freeDecompressionContext(lz4);
  }
};

StreamDecompressor::StreamDecompressor(Compression compression)
    : compression_(compression), state_(std::make_unique<State>()) {
  if (compression_ == Compression::Zstd) {
    state_->zstd = ZSTD_createDStream();
    if (!state_->zstd) throw std::runtime_error("zstd: cannot create a decompression context");
  } else if (compression_ == Compression::Lz4) {
    if (LZ4F_isError(LZ4F_createDecompressionContext(&state_->lz4, LZ4F_VERSION)))
      throw std::runtime_error("lz4: cannot create a decompression context");
  }
}

StreamDecompressor::~StreamDecompressor() = default;

namespace {
// Makes room for more output without passing limit; returns false when there is none left.
bool grow(std::vector<std::byte>& out, std::size_t used, std::uint64_t limit) {
  if (used < out.size()) return true;
  if (used >= limit) return false;
  const std::uint64_t want = std::max<std::uint64_t>(used * 2, used + (std::uint64_t{1} << 16));
  out.resize(static_cast<std::size_t>(std::min(want, limit)));
  return true;
}
}  // namespace

StreamDecompressor::Status StreamDecompressor::feed(std::span<const std::byte> in, std::vector<std::byte>& out,
                                                    std::uint64_t max_size, std::string& error) {
  const std::uint64_t limit = max_size + 1;  // one byte past the limit tells "too large" from "exactly full"
  std::size_t used = out.size();
  const auto finish = [&](Status s) {
    out.resize(used);
    return s;
  };
  if (compression_ == Compression::None) {
    if (out.size() + in.size() > max_size) return Status::kTooLarge;
    out.insert(out.end(), in.begin(), in.end());
    return Status::kOk;
  }
  if (in.empty()) return Status::kOk;
  if (compression_ == Compression::Zstd) {
    ZSTD_inBuffer src{in.data(), in.size(), 0};
    bool full = false;
    while (src.pos < src.size || full) {
      if (!grow(out, used, limit)) return finish(Status::kTooLarge);
      ZSTD_outBuffer dst{out.data() + used, out.size() - used, 0};
      const std::size_t r = ZSTD_decompressStream(state_->zstd, &dst, &src);
      if (ZSTD_isError(r)) {
        error = ZSTD_getErrorName(r);
        ZSTD_DCtx_reset(state_->zstd, ZSTD_reset_session_only);
        return finish(Status::kError);
      }
      used += dst.pos;
      full = dst.pos == dst.size;
      frame_complete_ = r == 0;  // 0: a frame ended and was fully flushed
      if (used > max_size) return finish(Status::kTooLarge);
    }
    return finish(Status::kOk);
  }
  // LZ4 frame: LZ4F_decompress returns 0 once a frame is complete, else a hint of the bytes it wants.
  std::size_t consumed = 0;
  bool full = false;
  while (consumed < in.size() || full) {
    if (!grow(out, used, limit)) return finish(Status::kTooLarge);
    const std::size_t room = out.size() - used;
    std::size_t dst_size = room, src_size = in.size() - consumed;
    const std::size_t r = LZ4F_decompress(state_->lz4, out.data() + used, &dst_size, in.data() + consumed, &src_size,
                                          nullptr);
    if (LZ4F_isError(r)) {
      error = LZ4F_getErrorName(r);
      LZ4F_resetDecompressionContext(state_->lz4);
      return finish(Status::kError);
    }
    consumed += src_size;
    used += dst_size;
    full = dst_size == room;
    frame_complete_ = r == 0;
    if (used > max_size) return finish(Status::kTooLarge);
    if (src_size == 0 && dst_size == 0) break;  // no progress possible with this input
  }
  return finish(Status::kOk);
}

}  // namespace stampscan::trace::detail
