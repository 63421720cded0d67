// McapWriter -> McapReader round trips: every message, schema, channel, metadata and attachment comes
// back, and the summary (statistics, chunk, attachment and metadata indexes, summary offsets) and the
// message indexes agree with what was written.
#include "mcap_test_support.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <stdexcept>
#include <tuple>

namespace stampscan::trace::test {
namespace {

struct Written {
  std::vector<Msg> messages;
  std::vector<Schema> schemas;
  std::vector<Channel> channels;
};

// Four channels on two schemas (and one without), 600 messages over 3 s including three multi-MB
// payloads, two metadata records and two attachments.
Written writeBigTrace(const fs::path& file, Compression compression) {
  McapWriterOptions options;
  options.compression = compression;
  options.chunk_size = 64 * 1024;
  McapWriter writer(file, options);
  Written w;
  const std::string cdr_schema = "float64 x\nfloat64 y\nfloat64 z\n";
  w.schemas.push_back({writer.addSchema("stampscan_msgs/CmmPosition", "ros2msg", std::string_view(cdr_schema)),
                       "stampscan_msgs/CmmPosition", "ros2msg",
                       std::vector<std::byte>(reinterpret_cast<const std::byte*>(cdr_schema.data()),
                                              reinterpret_cast<const std::byte*>(cdr_schema.data()) + cdr_schema.size())});
  const std::vector<std::byte> image_schema = payload(7, 300);
  w.schemas.push_back({writer.addSchema("stampscan_msgs/Image", "x-binary", image_schema), "stampscan_msgs/Image",
                       "x-binary", image_schema});
  const auto channel = [&](std::uint16_t schema, const std::string& topic, const std::string& encoding, KeyValues meta) {
    w.channels.push_back({writer.addChannel(schema, topic, encoding, meta), schema, topic, encoding, meta});
  };
  channel(w.schemas[0].id, "/cmm/position", "cdr", {{"device", "cmm"}, {"clock", "station"}});
  channel(w.schemas[1].id, "/camera/left/image", "cdr", {{"device", "camera-left"}});
  channel(w.schemas[1].id, "/camera/right/image", "cdr", {});
  channel(0, "/plc/state", "json", {{"note", "no schema"}});

  std::vector<std::uint32_t> sequence(5, 0);
  for (std::uint32_t i = 0; i < 600; ++i) {
    const std::uint16_t ch = w.channels[i % 4].id;
    std::size_t size = 20 + (i * 131) % 2000;
    if (i == 100 || i == 301 || i == 502) size = (i == 301 ? 5 : 3) * 1024 * 1024 + i;  // multi-MB images
    Msg m{ch, sequence[ch]++, 10'000'000'000ull + i * 5'000'000ull, 10'000'000'000ull + i * 5'000'000ull - 1000,
          payload(i + 1000, size), false};
    writer.write(m.channel, m.log_time, m.publish_time, m.data);
    w.messages.push_back(std::move(m));
    if (i == 200) writer.addMetadata("scan", {{"part", "pan-7"}, {"plan", "default"}});
    if (i == 400) writer.addAttachment("calibration.yaml", "text/yaml", 12'000'000'000ull, payload(5, 5000), 42);
  }
  writer.addMetadata("result", {});
  writer.addAttachment("empty.bin", "application/octet-stream", 13'000'000'000ull, {});
  writer.close();
  return w;
}

class RoundTrip : public TraceTest, public ::testing::WithParamInterface<Compression> {};

TEST_P(RoundTrip, EveryRecordComesBackAndTheSummaryAgrees) {
  const fs::path file = dir() / "big.mcap";
  const Written w = writeBigTrace(file, GetParam());
  McapReader reader(file);

  // Linear scan: all messages, in order, verified, and a healthy file.
  const ReadBack r = readAll(reader);
  EXPECT_TRUE(r.health.healthy());
  for (const Damage& d : r.health.damage) ADD_FAILURE() << "damage at " << d.offset << ": " << d.what;
  EXPECT_TRUE(r.health.data_crc_checked);
  EXPECT_TRUE(r.health.summary_crc_checked);
  ASSERT_EQ(r.messages.size(), w.messages.size());
  for (std::size_t i = 0; i < w.messages.size(); ++i) {
    ASSERT_EQ(r.messages[i], w.messages[i]) << "message " << i;
    ASSERT_TRUE(r.messages[i].verified) << "message " << i;
  }
  EXPECT_EQ(r.health.messages_unverified, 0u);
  ASSERT_TRUE(r.health.header);
  EXPECT_EQ(r.health.header->profile, "x-stampscan");
  EXPECT_EQ(r.health.header->library, "stampscan 0.1");
  EXPECT_EQ(r.health.compressions.count(compressionName(GetParam())), 1u);

  // Schemas and channels, as found in the data section and in the summary.
  std::vector<Damage> problems;
  const std::optional<Summary> s = reader.summary(&problems);
  ASSERT_TRUE(s) << (problems.empty() ? "" : problems[0].what);
  for (const auto* found : {&r.health.schemas, &s->schemas}) {
    ASSERT_EQ(found->size(), w.schemas.size());
    for (const Schema& schema : w.schemas) {
      const Schema& got = found->at(schema.id);
      EXPECT_EQ(got.name, schema.name);
      EXPECT_EQ(got.encoding, schema.encoding);
      EXPECT_EQ(got.data, schema.data);
    }
  }
  for (const auto* found : {&r.health.channels, &s->channels}) {
    ASSERT_EQ(found->size(), w.channels.size());
    for (const Channel& c : w.channels) {
      const Channel& got = found->at(c.id);
      EXPECT_EQ(got.schema_id, c.schema_id);
      EXPECT_EQ(got.topic, c.topic);
      EXPECT_EQ(got.message_encoding, c.message_encoding);
      EXPECT_EQ(got.metadata, c.metadata);
    }
  }

  // Statistics.
  ASSERT_TRUE(s->statistics);
  const Statistics& st = *s->statistics;
  EXPECT_EQ(st.message_count, w.messages.size());
  EXPECT_EQ(st.schema_count, w.schemas.size());
  EXPECT_EQ(st.channel_count, w.channels.size());
  EXPECT_EQ(st.attachment_count, 2u);
  EXPECT_EQ(st.metadata_count, 2u);
  EXPECT_EQ(st.chunk_count, s->chunk_indexes.size());
  EXPECT_EQ(st.chunk_count, r.health.chunks);
  EXPECT_GT(st.chunk_count, 10u);
  EXPECT_EQ(st.message_start_time, w.messages.front().log_time);
  EXPECT_EQ(st.message_end_time, w.messages.back().log_time);
  std::map<std::uint16_t, std::uint64_t> per_channel;
  for (const Msg& m : w.messages) ++per_channel[m.channel];
  EXPECT_EQ(st.channel_message_counts, per_channel);

  // Chunk indexes and message indexes: each chunk read through its index gives its messages, each
  // index entry points at the message it names, and together they are every message once.
  std::set<std::pair<std::uint16_t, std::uint32_t>> seen;
  std::uint64_t previous_end = 0;
  for (const ChunkIndex& c : s->chunk_indexes) {
    EXPECT_GE(c.chunk_start_offset, previous_end);
    previous_end = c.chunk_start_offset + c.chunk_length + c.message_index_length;
    EXPECT_EQ(c.compression == "" || c.compression == compressionName(GetParam()), true) << c.compression;
    EXPECT_LE(c.compressed_size, c.uncompressed_size);
    std::vector<TraceMessage> in_chunk;
    std::uint64_t last_time = 0;
    std::vector<Damage> chunk_problems;
    const bool ok = reader.readChunk(c, s->channels, [&](const TraceMessage& m) {
      EXPECT_GE(m.log_time, last_time) << "index order is log-time order";
      last_time = m.log_time;
      EXPECT_GE(m.log_time, c.message_start_time);
      EXPECT_LE(m.log_time, c.message_end_time);
      EXPECT_TRUE(m.verified);
      const Msg& original = w.messages.at([&] {
        for (std::size_t i = 0; i < w.messages.size(); ++i)
          if (w.messages[i].channel == m.channel_id && w.messages[i].sequence == m.sequence) return i;
        return w.messages.size();
      }());
      EXPECT_EQ(Msg({m.channel_id, m.sequence, m.log_time, m.publish_time,
                     std::vector<std::byte>(m.data.begin(), m.data.end()), true}),
                original);
      EXPECT_TRUE(seen.insert({m.channel_id, m.sequence}).second) << "message indexed twice";
      EXPECT_NE(m.channel, nullptr);
      return true;
    }, &chunk_problems);
    EXPECT_TRUE(ok) << (chunk_problems.empty() ? "" : chunk_problems[0].what);
    EXPECT_EQ(c.message_index_offsets.empty(), false);
  }
  EXPECT_EQ(seen.size(), w.messages.size());

  // Attachment and metadata indexes point at the records the scan found.
  ASSERT_EQ(s->attachment_indexes.size(), 2u);
  ASSERT_EQ(r.health.attachments.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(s->attachment_indexes[i].offset, r.health.attachments[i].offset);
    EXPECT_EQ(s->attachment_indexes[i].name, r.health.attachments[i].name);
    EXPECT_EQ(s->attachment_indexes[i].data_size, r.health.attachments[i].data_size);
    EXPECT_TRUE(r.health.attachments[i].crc_checked);
  }
  EXPECT_EQ(r.health.attachments[0].media_type, "text/yaml");
  EXPECT_EQ(r.health.attachments[0].create_time, 42u);
  EXPECT_EQ(r.health.attachments[0].data_size, 5000u);
  ASSERT_EQ(s->metadata_indexes.size(), 2u);
  ASSERT_EQ(r.health.metadata.size(), 2u);
  EXPECT_EQ(s->metadata_indexes[0].offset, r.health.metadata[0].offset);
  EXPECT_EQ(r.health.metadata[0].name, "scan");
  EXPECT_EQ(r.health.metadata[0].metadata.at("part"), "pan-7");
  EXPECT_EQ(r.health.metadata[1].name, "result");

  // Summary offsets: each group covers exactly the summary records of its opcode.
  std::set<std::uint8_t> groups;
  for (const SummaryOffset& g : s->summary_offsets) {
    EXPECT_TRUE(groups.insert(g.group_opcode).second);
    EXPECT_GE(g.group_start, s->footer.summary_start);
    EXPECT_LE(g.group_start + g.group_length, s->footer.summary_offset_start);
  }
  EXPECT_EQ(groups, (std::set<std::uint8_t>{0x03, 0x04, 0x08, 0x0A, 0x0B, 0x0D}));
}

INSTANTIATE_TEST_SUITE_P(Compression, RoundTrip, ::testing::Values(Compression::None, Compression::Zstd, Compression::Lz4),
                         compressionCase);

TEST_F(TraceTest, FiltersSelectChannelsTopicsAndTimes) {
  const fs::path file = dir() / "small.mcap";
  const std::vector<Msg> written = writeSmallTrace(file, Compression::Zstd);
  McapReader reader(file);
  ReadOptions by_topic;
  by_topic.topics = {"/laser/profile"};
  const ReadBack topic = readAll(reader, by_topic);
  ReadOptions by_channel;
  by_channel.channels = {1, 3};
  const ReadBack channel = readAll(reader, by_channel);
  ReadOptions by_time;
  by_time.start_time = written[10].log_time;
  by_time.end_time = written[19].log_time;
  const ReadBack time = readAll(reader, by_time);
  std::size_t laser = 0, one_or_three = 0;
  for (const Msg& m : written) {
    laser += m.channel == 2;
    one_or_three += m.channel != 2;
  }
  EXPECT_EQ(topic.messages.size(), laser);
  EXPECT_EQ(channel.messages.size(), one_or_three);
  ASSERT_EQ(time.messages.size(), 10u);
  EXPECT_EQ(time.messages.front(), written[10]);
  EXPECT_EQ(topic.health.messages_found, written.size());  // filters do not hide damage checks
  EXPECT_TRUE(topic.health.healthy());
}

TEST_F(TraceTest, CallbackStopsTheScan) {
  const fs::path file = dir() / "small.mcap";
  writeSmallTrace(file, Compression::None);
  McapReader reader(file);
  int seen = 0;
  const TraceHealth h = reader.readMessages([&](const TraceMessage&) { return ++seen < 5; });
  EXPECT_EQ(seen, 5);
  EXPECT_TRUE(h.stopped);
  EXPECT_FALSE(h.healthy());  // not all of it was checked
}

TEST_F(TraceTest, ChunksCloseAtTheirSizeOrTimeSpan) {
  const fs::path file = dir() / "span.mcap";
  {
    McapWriterOptions options;
    options.chunk_duration_ns = 1'000'000'000;
    McapWriter writer(file, options);
    const std::uint16_t c = writer.addChannel(0, "/t", "json");
    for (std::uint64_t i = 0; i < 50; ++i) writer.write(c, i * 300'000'000, i * 300'000'000, payload(i, 100));
    // destructor closes
  }
  McapReader reader(file);
  const std::optional<Summary> s = reader.summary();
  ASSERT_TRUE(s);
  EXPECT_GE(s->chunk_indexes.size(), 12u);
  for (const ChunkIndex& c : s->chunk_indexes) EXPECT_LE(c.message_end_time - c.message_start_time, 1'000'000'000u);
  EXPECT_TRUE(reader.check().healthy());
}

TEST_F(TraceTest, WriterErrorsNameTheProblem) {
  EXPECT_THROW(McapWriter(dir() / "missing" / "x.mcap"), std::runtime_error);
  try {
    McapWriter writer(dir() / "missing" / "x.mcap");
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing/x.mcap"), std::string::npos) << e.what();
  }
  McapWriter writer(dir() / "w.mcap");
  EXPECT_THROW(writer.write(1, 0, 0, {}), std::invalid_argument);
  EXPECT_THROW(writer.addChannel(3, "/x", "json"), std::invalid_argument);
  writer.close();
  EXPECT_FALSE(writer.isOpen());
  EXPECT_THROW(writer.addChannel(0, "/x", "json"), std::logic_error);
  writer.close();  // idempotent
  EXPECT_THROW(McapReader(dir() / "nothing.mcap"), std::runtime_error);
}

TEST_F(TraceTest, EmptyTraceIsValid) {
  const fs::path file = dir() / "empty.mcap";
  McapWriter(file).close();
  McapReader reader(file);
  const TraceHealth h = reader.check();
  EXPECT_TRUE(h.healthy());
  EXPECT_EQ(h.messages_found, 0u);
  const std::optional<Summary> s = reader.summary();
  ASSERT_TRUE(s);
  ASSERT_TRUE(s->statistics);
  EXPECT_EQ(s->statistics->message_count, 0u);
}

}  // namespace
}  // namespace stampscan::trace::test
