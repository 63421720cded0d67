// Fuzz target for the MCAP trace reader: the recovering linear scan, the summary and the indexed
// chunk reads on arbitrary bytes. The reader must never throw on content (only on I/O errors, which
// memory input has none of), and its report must be self-consistent.
#include "fuzz_targets.hpp"

#include "stampscan/acquisition/trace/mcap_reader.hpp"

#include <span>
#include <stdexcept>
#include <vector>

namespace stampscan::fuzz {

namespace {
// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}

// Reads every delivered byte, so that a span pointing outside live memory trips the sanitizer.
unsigned touch(std::span<const std::byte> data) {
  unsigned sum = 0;
  for (const std::byte b : data) sum += std::to_integer<unsigned>(b);
  return sum;
}
}  // namespace

int fuzzMcap(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data), size);
  trace::McapReader reader(bytes, "fuzz.mcap");
  trace::ReadOptions options;
  options.max_chunk_bytes = std::uint64_t{16} << 20;  // a decompression bomb must not exhaust memory
  std::uint64_t delivered = 0;
  unsigned sum = 0;
  const trace::TraceHealth h = reader.readMessages(
      [&](const trace::TraceMessage& m) {
        sum += touch(m.data);
        require(m.channel == nullptr || m.channel->id == m.channel_id, "message channel pointer names another channel");
        ++delivered;
        return true;
      },
      options);
  require(h.file_size == size, "health.file_size differs from the input size");
  require(delivered == h.messages_delivered, "messages_delivered differs from the callback count");
  require(h.messages_delivered <= h.messages_found, "more messages delivered than found");
  require(h.messages_unverified <= h.messages_found, "more unverified messages than found");
  require(!h.stopped, "stopped without being asked to");
  if (h.truncated) {
    require(h.truncated->file_size == size, "truncation not at the end of the input");
    require(h.truncated->record_offset + h.truncated->bytes_present == size, "cut record does not end at the cut");
    require(h.truncated->bytes_present < h.truncated->bytes_needed, "cut record is complete");
  }
  if (h.healthy()) require(h.damage.empty() && !h.truncated && !h.not_mcap, "healthy with damage");
  if (h.not_mcap) require(delivered == 0, "messages from a file that is not MCAP");

  // Stopping at once must hold too.
  const trace::TraceHealth stopped = reader.readMessages([](const trace::TraceMessage&) { return false; }, options);
  require(stopped.messages_delivered <= 1 && (stopped.messages_delivered == 0 || stopped.stopped),
          "the scan went on after the callback returned false");

  // The summary, and every chunk it indexes.
  std::vector<trace::Damage> problems;
  if (const std::optional<trace::Summary> s = reader.summary(&problems)) {
    require(problems.empty(), "summary returned along with problems");
    for (const trace::ChunkIndex& c : s->chunk_indexes) {
      reader.readChunk(
          c, s->channels,
          [&](const trace::TraceMessage& m) {
            sum += touch(m.data);
            return true;
          },
          &problems, options);
    }
  } else {
    require(!problems.empty(), "no summary and no reason given");
  }
  return static_cast<int>(sum & 0);
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzMcap(data, size);
}
#endif
