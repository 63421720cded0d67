// Interoperability with the reference MCAP implementation: traces written by McapWriter are read by
// @mcap/core (TypeScript, run with node) through its indexed reader and its streaming reader, and
// traces written by @mcap/core's writer are read by McapReader. Both sides summarise each channel as
// a count and a CRC-32 over its messages (see interop/mcap_interop.mjs), which must agree.
//
// Needs node and the packages of interop/package.json (scripts/setup.sh installs them); without them
// the tests are skipped with the reason.
#include "mcap_codec.hpp"  // the library's CRC-32 (zlib's)
#include "mcap_test_support.hpp"

#include <cstdlib>
#include <map>
#include <sstream>

#ifndef STAMPSCAN_MCAP_INTEROP_DIR
#error "STAMPSCAN_MCAP_INTEROP_DIR must name tests/acquisition/interop"
#endif

namespace stampscan::trace::test {
namespace {

std::string shellQuote(const std::string& word) {
  std::string q = "'";
  for (const char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string readText(const fs::path& file) {
  std::ifstream in(file);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The same summary as mcap_interop.mjs: per channel, in sequence order, CRC-32 over sequence (u32
// LE), log time, publish time (u64 LE) and the data.
std::map<std::uint16_t, std::pair<std::size_t, std::uint32_t>> channelSums(std::vector<Msg> messages) {
  std::sort(messages.begin(), messages.end(), [](const Msg& a, const Msg& b) {
    return std::tie(a.channel, a.sequence) < std::tie(b.channel, b.sequence);
  });
  std::map<std::uint16_t, std::pair<std::size_t, std::uint32_t>> sums;
  for (const Msg& m : messages) {
    auto& [count, crc] = sums[m.channel];
    unsigned char head[20];
    for (int i = 0; i < 4; ++i) head[i] = static_cast<unsigned char>(m.sequence >> (8 * i));
    for (int i = 0; i < 8; ++i) head[4 + i] = static_cast<unsigned char>(m.log_time >> (8 * i));
    for (int i = 0; i < 8; ++i) head[12 + i] = static_cast<unsigned char>(m.publish_time >> (8 * i));
    crc = detail::crc32(crc, std::as_bytes(std::span<const unsigned char>(head)));
    crc = detail::crc32(crc, m.data);
    ++count;
  }
  return sums;
}

std::string hex8(std::uint32_t v) {
  char text[16];
  std::snprintf(text, sizeof text, "%08x", v);
  return text;
}

class Interop : public TraceTest {
 protected:
  void SetUp() override {
    TraceTest::SetUp();
    const fs::path folder = STAMPSCAN_MCAP_INTEROP_DIR;
    if (std::system("node --version >/dev/null 2>&1") != 0)
      GTEST_SKIP() << "node is not installed: run scripts/setup.sh (it installs nodejs and npm)";
    for (const char* package : {"@mcap/core", "fzstd"}) {
      if (!fs::exists(folder / "node_modules" / package / "package.json"))
        GTEST_SKIP() << "npm package " << package << " is missing in " << folder.string()
                     << "/node_modules: run scripts/setup.sh (npm ci --prefix tests/acquisition/interop)";
    }
  }

  // Runs the script; returns its stdout lines, failing the test on a non-zero exit.
  std::vector<std::string> node(const std::string& args) {
    const fs::path out = dir() / "node.out", err = dir() / "node.err";
    const std::string command = "node " + shellQuote((fs::path(STAMPSCAN_MCAP_INTEROP_DIR) / "mcap_interop.mjs").string()) +
                                " " + args + " >" + shellQuote(out.string()) + " 2>" + shellQuote(err.string());
    const int status = std::system(command.c_str());
    EXPECT_EQ(status, 0) << command << "\n" << readText(err);
    std::vector<std::string> lines;
    std::istringstream text(readText(out));
    for (std::string line; std::getline(text, line);) lines.push_back(line);
    return lines;
  }
};

bool has(const std::vector<std::string>& lines, const std::string& line) {
  return std::find(lines.begin(), lines.end(), line) != lines.end();
}

std::string dump(const std::vector<std::string>& lines) {
  std::string all;
  for (const std::string& l : lines) all += l + "\n";
  return all;
}

TEST_F(Interop, ReferenceReaderReadsOurTraces) {
  for (const Compression compression : {Compression::Zstd, Compression::None}) {
    const fs::path file = dir() / ("ours_" + compressionName(compression) + ".mcap");
    McapWriterOptions options;
    options.compression = compression;
    options.chunk_size = 16 * 1024;
    std::vector<Msg> written;
    const std::vector<std::byte> attachment = payload(3, 3000);
    {
      McapWriter writer(file, options);
      const std::uint16_t schema = writer.addSchema("stampscan_msgs/LaserProfile", "ros2msg", std::string_view("float32[] z\n"));
      const std::uint16_t channels[3] = {writer.addChannel(schema, "/laser/profile", "cdr", {{"device", "digitizer"}}),
                                         writer.addChannel(schema, "/laser/profile2", "cdr", {}),
                                         writer.addChannel(0, "/plc/state", "json", {})};
      std::uint32_t sequence[3] = {};
      for (std::uint32_t i = 0; i < 500; ++i) {
        const std::size_t c = (i * 7) % 3;
        const std::size_t size = i == 250 ? 2 * 1024 * 1024 : 8 + (i * 53) % 900;
        written.push_back({channels[c], sequence[c]++, 7'000'000'000ull + i * 2'000'000ull, 6'000'000'000ull + i, payload(i, size), false});
        writer.write(written.back().channel, written.back().log_time, written.back().publish_time, written.back().data);
        if (i == 100) writer.addAttachment("part.stl", "model/stl", 7'200'000'000ull, attachment);
      }
      writer.addMetadata("scan", {{"part", "pan"}, {"seed", "1"}});
      writer.close();
    }
    const std::vector<std::string> lines = node("read " + shellQuote(file.string()));
    SCOPED_TRACE(compressionName(compression) + ":\n" + dump(lines));
    EXPECT_TRUE(has(lines, "header profile=x-stampscan library=stampscan 0.1"));
    McapReader reader(file);
    const std::optional<Summary> s = reader.summary();
    ASSERT_TRUE(s);
    EXPECT_TRUE(has(lines, "statistics messages=500 schemas=1 channels=3 attachments=1 metadata=1 chunks=" +
                               std::to_string(s->chunk_indexes.size()) + " start=7000000000 end=" +
                               std::to_string(7'000'000'000ull + 499 * 2'000'000ull)));
    EXPECT_TRUE(has(lines, "chunkindexes count=" + std::to_string(s->chunk_indexes.size())));
    EXPECT_TRUE(has(lines, "datacrc ok"));
    // The streaming reader got to the footer and the closing magic.
    bool stream_done = false;
    for (const std::string& l : lines) stream_done |= l.rfind("stream done=true", 0) == 0;
    EXPECT_TRUE(stream_done);
    EXPECT_TRUE(has(lines, "attachment name=part.stl media=model/stl size=3000 crc=" +
                               hex8(detail::crc32(0, attachment))));
    EXPECT_TRUE(has(lines, "metadata name=scan keys=part:pan,seed:1"));
    const std::map<std::uint16_t, std::string> topics{{1, "/laser/profile"}, {2, "/laser/profile2"}, {3, "/plc/state"}};
    for (const auto& [channel, sum] : channelSums(written)) {
      const std::string schema = channel == 3 ? "" : "stampscan_msgs/LaserProfile";
      const std::string tail = " channel=" + std::to_string(channel) + " topic=" + topics.at(channel) + " schema=" + schema +
                               " count=" + std::to_string(sum.first) + " crc=" + hex8(sum.second);
      EXPECT_TRUE(has(lines, "indexed" + tail)) << "indexed" << tail;
      EXPECT_TRUE(has(lines, "stream" + tail)) << "stream" << tail;
    }
  }
}

TEST_F(Interop, WeReadTheReferenceWritersTraces) {
  for (const std::string mode : {"chunked", "unchunked"}) {
    const fs::path file = dir() / ("theirs_" + mode + ".mcap");
    const std::vector<std::string> lines = node("write " + shellQuote(file.string()) + " " + mode);
    SCOPED_TRACE(mode + ":\n" + dump(lines));
    ASSERT_EQ(lines.size(), 2u);
    McapReader reader(file);
    const ReadBack r = readAll(reader);
    for (const Damage& d : r.health.damage) ADD_FAILURE() << "damage at " << d.offset << ": " << d.what;
    EXPECT_TRUE(r.health.healthy());
    EXPECT_TRUE(r.health.data_crc_checked);
    EXPECT_TRUE(r.health.summary_crc_checked);
    EXPECT_EQ(r.health.chunks > 0, mode == "chunked");
    for (const auto& [channel, sum] : channelSums(r.messages)) {
      const Channel* c = r.health.channels.count(channel) ? &r.health.channels.at(channel) : nullptr;
      ASSERT_NE(c, nullptr) << channel;
      const std::string schema = c->schema_id ? r.health.schemas.at(c->schema_id).name : "";
      const std::string line = "written channel=" + std::to_string(channel) + " topic=" + c->topic + " schema=" + schema +
                               " count=" + std::to_string(sum.first) + " crc=" + hex8(sum.second);
      EXPECT_TRUE(has(lines, line)) << line;
    }
    ASSERT_EQ(r.health.metadata.size(), 1u);
    EXPECT_EQ(r.health.metadata[0].metadata.at("from"), "typescript");
    const std::optional<Summary> s = reader.summary();
    ASSERT_TRUE(s);
    ASSERT_TRUE(s->statistics);
    EXPECT_EQ(s->statistics->message_count, r.messages.size());
  }
}

}  // namespace
}  // namespace stampscan::trace::test
