// Traces laid out the way other MCAP writers do it, built record by record: messages outside chunks,
// schemas and channels inside chunks, lz4, multi-frame zstd, chunks without CRC, channel id 0,
// application records (opcode >= 0x80), no summary, no Data End. All of it legal MCAP (bar the
// missing Data End) that the reader must take.
#include "mcap_codec.hpp"
#include "mcap_compression.hpp"
#include "mcap_test_support.hpp"

namespace stampscan::trace::test {
namespace {

using detail::RecordBuilder;

struct Built {
  std::vector<std::byte> bytes;
  std::vector<Msg> messages;  // in file order, with `verified` as the reader should report it
};

void message(RecordBuilder& out, std::vector<Msg>& all, std::uint16_t channel, std::uint32_t sequence, bool verified) {
  Msg m{channel, sequence, 5000 + all.size(), 4000 + all.size(), payload(all.size() + 77, 30 + all.size() * 3), verified};
  detail::appendMessage(out, m.channel, m.sequence, m.log_time, m.publish_time, m.data);
  all.push_back(std::move(m));
}

void chunk(RecordBuilder& out, const std::vector<std::byte>& records, Compression compression, bool crc,
           bool two_frames = false) {
  std::vector<std::byte> stored;
  detail::ChunkCompressor compressor(compression, compression == Compression::Lz4 ? 0 : 3);
  if (two_frames) {  // zstd readers must take concatenated frames
    const std::size_t half = records.size() / 2;
    std::vector<std::byte> second;
    compressor.compress(std::span<const std::byte>(records).first(half), stored);
    compressor.compress(std::span<const std::byte>(records).subspan(half), second);
    stored.insert(stored.end(), second.begin(), second.end());
  } else {
    compressor.compress(records, stored);
  }
  const std::size_t r = out.begin(Opcode::Chunk);
  out.u64(5000);
  out.u64(6000);
  out.u64(records.size());
  out.u32(crc ? detail::crc32(0, records) : 0);
  out.string(compressionName(compression));
  out.u64(stored.size());
  out.raw(stored);
  out.end(r);
}

Built buildForeign(bool with_data_end) {
  Built b;
  RecordBuilder out;
  out.raw(std::span<const std::byte>(reinterpret_cast<const std::byte*>(kMcapMagic.data()), kMcapMagic.size()));
  detail::appendHeader(out, {"ros2", "some other writer"});
  const std::size_t app = out.begin(static_cast<Opcode>(0x80));  // an application's own record
  out.u32(0xDEADBEEF);
  out.end(app);
  detail::appendSchema(out, {1, "a.Msg", "ros2msg", {std::byte{'x'}}});
  detail::appendChannel(out, {0, 1, "/a", "cdr", {{"k", "v"}}});
  for (std::uint32_t i = 0; i < 3; ++i) message(out, b.messages, 0, i, false);

  RecordBuilder inner;  // schema and channel inside the chunk, before their messages
  detail::appendSchema(inner, {2, "b.Msg", "ros2msg", {}});
  detail::appendChannel(inner, {7, 2, "/b", "cdr", {}});
  for (std::uint32_t i = 0; i < 3; ++i) message(inner, b.messages, 7, i, true);
  message(inner, b.messages, 0, 3, true);
  chunk(out, inner.bytes(), Compression::Lz4, true);

  inner.clear();
  for (std::uint32_t i = 3; i < 5; ++i) message(inner, b.messages, 7, i, false);
  chunk(out, inner.bytes(), Compression::Zstd, false, true);

  inner.clear();
  message(inner, b.messages, 0, 4, true);
  chunk(out, inner.bytes(), Compression::None, true);

  // An attachment without CRC, then more messages outside chunks.
  const std::size_t a = out.begin(Opcode::Attachment);
  out.u64(1);
  out.u64(2);
  out.string("notes.txt");
  out.string("text/plain");
  out.u64(3);
  out.raw(detail::asBytes("abc"));
  out.u32(0);
  out.end(a);
  message(out, b.messages, 7, 5, false);
  if (with_data_end) detail::appendDataEnd(out, 0);
  const std::size_t f = out.begin(Opcode::Footer);
  out.u64(0);
  out.u64(0);
  out.u32(0);
  out.end(f);
  out.raw(std::span<const std::byte>(reinterpret_cast<const std::byte*>(kMcapMagic.data()), kMcapMagic.size()));
  b.bytes = out.bytes();
  return b;
}

TEST(ForeignTrace, EveryLayoutIsRead) {
  const Built b = buildForeign(true);
  const ReadBack r = readAll(b.bytes);
  for (const Damage& d : r.health.damage) ADD_FAILURE() << "damage at " << d.offset << ": " << d.what;
  EXPECT_TRUE(r.health.healthy());
  EXPECT_FALSE(r.health.data_crc_checked);  // the writer left the CRC out
  ASSERT_EQ(r.messages.size(), b.messages.size());
  for (std::size_t i = 0; i < b.messages.size(); ++i) {
    EXPECT_EQ(r.messages[i], b.messages[i]) << "message " << i;
    EXPECT_EQ(r.messages[i].verified, b.messages[i].verified) << "message " << i;
  }
  EXPECT_EQ(r.health.unknown_records, 1u);
  EXPECT_EQ(r.health.channels.size(), 2u);
  EXPECT_EQ(r.health.channels.at(7).topic, "/b");
  EXPECT_EQ(r.health.schemas.size(), 2u);
  EXPECT_EQ(r.health.chunks, 3u);
  EXPECT_EQ(r.health.compressions, (std::set<std::string>{"", "lz4", "zstd"}));
  ASSERT_EQ(r.health.attachments.size(), 1u);
  EXPECT_FALSE(r.health.attachments[0].crc_checked);
  EXPECT_EQ(r.health.attachments[0].name, "notes.txt");

  ReadOptions only_b;
  only_b.topics = {"/b"};
  EXPECT_EQ(readAll(b.bytes, only_b).messages.size(), 6u);
  McapReader reader(b.bytes, "foreign");
  std::vector<Damage> problems;
  EXPECT_FALSE(reader.summary(&problems));  // it has none, and says so
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0].kind, DamageKind::BadSummary);
}

TEST(ForeignTrace, MissingDataEndIsReportedButEverythingIsRead) {
  const Built b = buildForeign(false);
  const ReadBack r = readAll(b.bytes);
  ASSERT_EQ(r.messages.size(), b.messages.size());
  ASSERT_EQ(r.health.damage.size(), 1u);
  EXPECT_EQ(r.health.damage[0].kind, DamageKind::MissingDataEnd);
  EXPECT_TRUE(r.health.footer_found);
  EXPECT_FALSE(r.health.healthy());
}

TEST(ForeignTrace, CutForeignTraceYieldsAPrefix) {
  const Built b = buildForeign(true);
  for (std::size_t cut = 0; cut < b.bytes.size(); ++cut) {
    const ReadBack r = readAll(std::span<const std::byte>(b.bytes.data(), cut));
    ASSERT_TRUE(r.health.truncated) << cut;
    EXPECT_EQ(r.health.truncated->file_size, cut);
    ASSERT_LE(r.messages.size(), b.messages.size());
    for (std::size_t i = 0; i < r.messages.size(); ++i) ASSERT_EQ(r.messages[i], b.messages[i]) << "cut " << cut;
    EXPECT_TRUE(r.health.damage.empty()) << "cut " << cut << ": " << r.health.damage[0].what;
  }
}

}  // namespace
}  // namespace stampscan::trace::test
