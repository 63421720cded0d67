// A trace cut at every byte offset (a crash or power cut while recording): the reader never fails,
// delivers exactly a prefix of the written messages, at least every message whose chunk was complete
// (and, in uncompressed chunks, every message record that was complete), and reports the cut where
// the file ends.
#include "mcap_test_support.hpp"

#include <algorithm>
#include <chrono>

namespace stampscan::trace::test {
namespace {

// Where each message's chunk ends, and where its own record ends (in uncompressed chunks), in the
// intact file; learnt through the summary and the message indexes.
struct Layout {
  std::vector<std::uint64_t> chunk_end;   // per written message
  std::vector<std::uint64_t> record_end;  // per written message; = chunk_end for compressed chunks
};

Layout layoutOf(McapReader& reader, const std::vector<Msg>& written) {
  Layout layout;
  layout.chunk_end.assign(written.size(), 0);
  layout.record_end.assign(written.size(), 0);
  const std::optional<Summary> s = reader.summary();
  EXPECT_TRUE(s);
  if (!s) return layout;
  for (const ChunkIndex& c : s->chunk_indexes) {
    const std::uint64_t end = c.chunk_start_offset + c.chunk_length;
    reader.readChunk(c, s->channels, [&](const TraceMessage& m) {
      for (std::size_t i = 0; i < written.size(); ++i) {
        if (written[i].channel != m.channel_id || written[i].sequence != m.sequence) continue;
        layout.chunk_end[i] = layout.record_end[i] = end;  // refined below for uncompressed chunks
      }
      return true;
    });
  }
  return layout;
}

class Truncation : public TraceTest, public ::testing::WithParamInterface<Compression> {};

TEST_P(Truncation, EveryCutYieldsAPrefixAndSaysWhere) {
  const fs::path file = dir() / "small.mcap";
  const std::vector<Msg> written = writeSmallTrace(file, GetParam());
  const std::vector<std::byte> bytes = readBytes(file);
  McapReader intact(file);
  ASSERT_TRUE(intact.check().healthy());

  // Record ends in uncompressed chunks, from the message index offsets: the record at offset o in
  // the records holds 9 + 22 + data bytes.
  Layout layout = layoutOf(intact, written);
  if (GetParam() == Compression::None) {
    const std::optional<Summary> s = intact.summary();
    ASSERT_TRUE(s);
    for (const ChunkIndex& c : s->chunk_indexes) {
      ASSERT_EQ(c.compression, "");
      const std::uint64_t records_at = c.chunk_start_offset + 9 + 8 + 8 + 8 + 4 + 4 + 8;
      // Walk the chunk's records in the file itself: they are stored as is.
      std::uint64_t at = records_at;
      const std::uint64_t end = records_at + c.uncompressed_size;
      std::size_t found = 0;
      while (at < end) {
        std::uint64_t length = 0;
        for (int b = 7; b >= 0; --b) length = (length << 8) | std::to_integer<std::uint64_t>(bytes[at + 1 + b]);
        const std::uint16_t channel = static_cast<std::uint16_t>(std::to_integer<unsigned>(bytes[at + 9]) |
                                                                 (std::to_integer<unsigned>(bytes[at + 10]) << 8));
        std::uint32_t sequence = 0;
        for (int b = 3; b >= 0; --b) sequence = (sequence << 8) | std::to_integer<std::uint32_t>(bytes[at + 11 + b]);
        for (std::size_t i = 0; i < written.size(); ++i)
          if (written[i].channel == channel && written[i].sequence == sequence) layout.record_end[i] = at + 9 + length;
        at += 9 + length;
        ++found;
      }
      ASSERT_GT(found, 0u);
    }
  }
  for (std::size_t i = 0; i < written.size(); ++i) {
    ASSERT_GT(layout.chunk_end[i], 0u) << "message " << i << " in no chunk";
    ASSERT_GT(layout.record_end[i], 0u) << "message " << i;
  }

  const auto t0 = std::chrono::steady_clock::now();
  std::size_t partial_recoveries = 0;
  for (std::size_t cut = 0; cut < bytes.size(); ++cut) {
    const ReadBack r = readAll(std::span<const std::byte>(bytes.data(), cut));
    ASSERT_LE(r.messages.size(), written.size()) << "cut " << cut;
    for (std::size_t i = 0; i < r.messages.size(); ++i)
      ASSERT_EQ(r.messages[i], written[i]) << "cut at byte " << cut << ": message " << i << " is not the written one";
    std::size_t complete = 0;
    while (complete < written.size() && layout.record_end[complete] <= cut) ++complete;
    ASSERT_GE(r.messages.size(), complete) << "cut at byte " << cut << ": messages before the cut were lost";
    partial_recoveries += r.messages.size() > 0 && layout.chunk_end[r.messages.size() - 1] > cut;

    ASSERT_TRUE(r.health.truncated) << "cut at byte " << cut << " not reported";
    EXPECT_EQ(r.health.truncated->file_size, cut);
    EXPECT_LE(r.health.truncated->record_offset, cut) << "cut " << cut;
    EXPECT_LT(r.health.truncated->bytes_present, std::max<std::uint64_t>(r.health.truncated->bytes_needed, 1))
        << "cut " << cut << " in " << r.health.truncated->record;
    EXPECT_EQ(r.health.truncated->record_offset + r.health.truncated->bytes_present, cut)
        << "cut " << cut << " in " << r.health.truncated->record;
    EXPECT_FALSE(r.health.healthy());
    EXPECT_FALSE(r.health.not_mcap) << "cut " << cut;
    for (const Damage& d : r.health.damage)
      ADD_FAILURE() << "cut at byte " << cut << " reported as damage at " << d.offset << ": " << d.what;
    if (HasFailure()) break;
  }
  // Uncompressed chunks give up their complete records before the chunk itself is complete.
  if (GetParam() == Compression::None) {
    EXPECT_GT(partial_recoveries, 0u);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  RecordProperty("cuts", static_cast<int>(bytes.size()));
  RecordProperty("seconds", std::to_string(seconds));
}

INSTANTIATE_TEST_SUITE_P(Compression, Truncation, ::testing::Values(Compression::None, Compression::Zstd, Compression::Lz4),
                         compressionCase);

// zstd and lz4 chunks are decoded as far as their cut bytes go: a chunk of many compressed blocks
// (zstd blocks hold up to 128 KiB, lz4 frame blocks 64 KiB) yields the messages of its complete blocks.
TEST_P(Truncation, CutInsideALargeChunkYieldsItsDecodableMessages) {
  const fs::path file = dir() / "large.mcap";
  std::vector<Msg> written;
  {
    McapWriterOptions options;
    options.compression = GetParam();
    options.chunk_size = 8 << 20;
    options.chunk_duration_ns = ~0ull;
    McapWriter writer(file, options);
    const std::uint16_t c = writer.addChannel(0, "/camera/left/image", "x-raw");
    for (std::uint32_t i = 0; i < 600; ++i) {
      written.push_back({c, i, 1000 + i, 1000 + i, payload(i, 2000), false});
      writer.write(c, 1000 + i, 1000 + i, written.back().data);
    }
  }
  const std::vector<std::byte> bytes = readBytes(file);
  for (const double fraction : {0.3, 0.6, 0.9}) {
    const auto cut = static_cast<std::size_t>(static_cast<double>(bytes.size()) * fraction);
    const ReadBack r = readAll(std::span<const std::byte>(bytes.data(), cut));
    ASSERT_TRUE(r.health.truncated);
    EXPECT_EQ(r.health.truncated->record, "Chunk");
    EXPECT_GT(r.messages.size(), static_cast<std::size_t>(600 * fraction * 0.5)) << "cut at " << fraction;
    EXPECT_EQ(r.health.messages_unverified, r.messages.size());
    for (std::size_t i = 0; i < r.messages.size(); ++i) {
      ASSERT_EQ(r.messages[i], written[i]);
      EXPECT_FALSE(r.messages[i].verified);
    }
  }
}

// A cut of a file on disk (what a crash leaves) reads the same as a cut in memory.
TEST_F(TraceTest, CutFileOnDisk) {
  const fs::path file = dir() / "small.mcap";
  const std::vector<Msg> written = writeSmallTrace(file, Compression::Zstd);
  std::vector<std::byte> bytes = readBytes(file);
  bytes.resize(bytes.size() * 2 / 3);
  writeBytes(dir() / "cut.mcap", bytes);
  McapReader reader(dir() / "cut.mcap");
  const ReadBack r = readAll(reader);
  ASSERT_TRUE(r.health.truncated);
  EXPECT_EQ(r.health.truncated->file_size, bytes.size());
  EXPECT_GT(r.messages.size(), written.size() / 3);
  for (std::size_t i = 0; i < r.messages.size(); ++i) EXPECT_EQ(r.messages[i], written[i]);
  EXPECT_FALSE(reader.summary());
}

}  // namespace
}  // namespace stampscan::trace::test
