// Damaged traces: every byte of a small trace flipped in turn must be noticed (the file never reads
// as healthy), must not crash the reader, and must not let a message with altered content through;
// one flipped byte costs at most one chunk of messages. Plus targeted damage: a bad chunk CRC, a
// garbage run in the middle, a file that is no MCAP at all.
#include "mcap_test_support.hpp"

#include <algorithm>
#include <map>

namespace stampscan::trace::test {
namespace {

// Largest number of messages in one chunk of the intact trace.
std::size_t largestChunk(McapReader& reader) {
  const std::optional<Summary> s = reader.summary();
  std::size_t most = 0;
  if (!s) return 0;
  for (const ChunkIndex& c : s->chunk_indexes) {
    std::size_t n = 0;
    reader.readChunk(c, s->channels, [&](const TraceMessage&) { return ++n > 0; });
    most = std::max(most, n);
  }
  return most;
}

// Every delivered message is one of the written ones, unaltered, in the written order.
void expectFaithfulSubsequence(const std::vector<Msg>& got, const std::vector<Msg>& written, const std::string& where) {
  std::size_t next = 0;
  for (const Msg& m : got) {
    while (next < written.size() && !(written[next].channel == m.channel && written[next].sequence == m.sequence)) ++next;
    ASSERT_LT(next, written.size()) << where << ": delivered " << m << ", not written (or out of order)";
    ASSERT_EQ(m, written[next]) << where << ": delivered with altered content";
    ++next;
  }
}

class FlippedByte : public TraceTest, public ::testing::WithParamInterface<Compression> {};

TEST_P(FlippedByte, IsReportedAndNeverDeliversAlteredMessages) {
  const fs::path file = dir() / "small.mcap";
  const std::vector<Msg> written = writeSmallTrace(file, GetParam());
  std::vector<std::byte> bytes = readBytes(file);
  McapReader intact(file);
  const std::size_t most = largestChunk(intact);
  ASSERT_GT(most, 0u);

  std::map<DamageKind, int> kinds;
  for (std::size_t at = 0; at < bytes.size(); ++at) {
    bytes[at] ^= std::byte{0xFF};
    const ReadBack r = readAll(bytes);
    bytes[at] ^= std::byte{0xFF};
    const std::string where = "byte " + std::to_string(at) + " flipped";
    EXPECT_FALSE(r.health.healthy()) << where << " reads as healthy";
    EXPECT_TRUE(!r.health.damage.empty() || r.health.truncated) << where << ": nothing reported";
    expectFaithfulSubsequence(r.messages, written, where);
    EXPECT_GE(r.messages.size() + most, written.size()) << where << ": more than one chunk of messages lost";
    for (const Damage& d : r.health.damage) ++kinds[d.kind];
    if (HasFailure()) break;
  }
  // The damage was told apart, not lumped together.
  EXPECT_GT(kinds[DamageKind::ChunkCrcMismatch] + kinds[DamageKind::ChunkUndecodable], 0);
  EXPECT_GT(kinds[DamageKind::DataSectionCrcMismatch], 0);
  EXPECT_GT(kinds[DamageKind::SummaryCrcMismatch], 0);
  EXPECT_GT(kinds[DamageKind::BadMagic], 0);
  EXPECT_GT(kinds[DamageKind::Resynchronised], 0);
}

INSTANTIATE_TEST_SUITE_P(Compression, FlippedByte, ::testing::Values(Compression::None, Compression::Zstd),
                         compressionCase);

TEST_F(TraceTest, ChunkCrcMismatchDropsOnlyThatChunk) {
  const fs::path file = dir() / "small.mcap";
  const std::vector<Msg> written = writeSmallTrace(file, Compression::None);
  std::vector<std::byte> bytes = readBytes(file);
  McapReader intact(file);
  const std::optional<Summary> s = intact.summary();
  ASSERT_TRUE(s);
  ASSERT_GE(s->chunk_indexes.size(), 3u);
  const ChunkIndex& c = s->chunk_indexes[1];
  bytes[c.chunk_start_offset + c.chunk_length - 3] ^= std::byte{0x01};  // last byte of a payload
  const ReadBack r = readAll(bytes);
  ASSERT_FALSE(r.health.damage.empty());
  EXPECT_EQ(r.health.damage[0].kind, DamageKind::ChunkCrcMismatch);
  EXPECT_EQ(r.health.damage[0].offset, c.chunk_start_offset);
  EXPECT_EQ(r.health.chunks_damaged, 1u);
  std::size_t in_chunk = 0;
  intact.readChunk(c, s->channels, [&](const TraceMessage&) { return ++in_chunk > 0; });
  EXPECT_EQ(r.health.messages_lost, in_chunk);
  EXPECT_EQ(r.messages.size() + in_chunk, written.size());
  expectFaithfulSubsequence(r.messages, written, "bad chunk");
  EXPECT_FALSE(r.health.data_crc_checked);
  EXPECT_TRUE(r.health.summary_crc_checked);
}

TEST_F(TraceTest, GarbageInTheMiddleIsSkippedToTheNextValidChunk) {
  const fs::path file = dir() / "small.mcap";
  const std::vector<Msg> written = writeSmallTrace(file, Compression::Zstd);
  std::vector<std::byte> bytes = readBytes(file);
  McapReader intact(file);
  const std::optional<Summary> s = intact.summary();
  ASSERT_TRUE(s);
  ASSERT_GE(s->chunk_indexes.size(), 4u);
  // Overwrite the second chunk and its message indexes with noise.
  const ChunkIndex& c = s->chunk_indexes[1];
  const std::vector<std::byte> noise = payload(1234, c.chunk_length + c.message_index_length);
  std::copy(noise.begin(), noise.end(), bytes.begin() + static_cast<std::ptrdiff_t>(c.chunk_start_offset));
  const ReadBack r = readAll(bytes);
  expectFaithfulSubsequence(r.messages, written, "noise");
  bool resynced = false;
  for (const Damage& d : r.health.damage) resynced |= d.kind == DamageKind::Resynchronised;
  EXPECT_TRUE(resynced);
  std::size_t in_chunk = 0;
  intact.readChunk(c, s->channels, [&](const TraceMessage&) { return ++in_chunk > 0; });
  EXPECT_EQ(r.messages.size() + in_chunk, written.size());
  EXPECT_TRUE(r.health.data_end_found);
}

TEST_F(TraceTest, OtherFilesAreNotMcap) {
  for (const std::string& text : {std::string("ply\nformat ascii 1.0\nend_header\n"), std::string("x"),
                                  std::string(100, '\0')}) {
    const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(text.data()), text.size());
    const ReadBack r = readAll(bytes);
    EXPECT_TRUE(r.health.not_mcap) << text;
    EXPECT_FALSE(r.health.healthy());
    EXPECT_TRUE(r.messages.empty());
  }
}

}  // namespace
}  // namespace stampscan::trace::test
