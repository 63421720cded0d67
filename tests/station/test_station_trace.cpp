// End-to-end tests of `station trace info`: a healthy trace (exit 0 and its key lines), a cut one and
// a damaged one (exit 1 with the report and byte offsets), and files that are missing or not MCAP
// (exit 1, one line naming the file).
#include "station_test_support.hpp"

#include "stampscan/acquisition/trace/mcap_writer.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace stampscan::station::test {
namespace {

// Two channels: 100 position reports at 100 Hz and 20 laser profiles at 20 Hz, a metadata record and
// an attachment, in zstd chunks of 4 KiB.
fs::path writeTrace(const fs::path& file) {
  trace::McapWriterOptions options;
  options.chunk_size = 4096;
  trace::McapWriter writer(file, options);
  const std::uint16_t schema = writer.addSchema("stampscan_msgs/CmmPosition", "ros2msg", std::string_view("float64 x\n"));
  const std::uint16_t cmm = writer.addChannel(schema, "/cmm/position", "cdr", {{"device", "cmm"}});
  const std::uint16_t laser = writer.addChannel(0, "/laser/profile", "x-raw");
  const std::uint64_t t0 = 1'700'000'000'000'000'000ull;
  std::vector<std::byte> data(200);
  for (int i = 0; i < 100; ++i) {
    for (std::size_t k = 0; k < data.size(); ++k) data[k] = static_cast<std::byte>((i + k / 8) & 0xFF);
    writer.write(cmm, t0 + static_cast<std::uint64_t>(i) * 10'000'000, t0, data);
    if (i % 5 == 0) writer.write(laser, t0 + static_cast<std::uint64_t>(i) * 10'000'000 + 1, t0, data);
  }
  writer.addMetadata("scan", {{"part", "pan"}});
  writer.addAttachment("cell.yaml", "text/yaml", t0, std::vector<std::byte>(300, std::byte{'a'}));
  writer.close();
  return file;
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST_F(StationTest, TraceInfoDescribesAHealthyTrace) {
  const fs::path file = writeTrace(work() / "scan.mcap");
  const RunResult r = run("trace info " + quote(file));
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  for (const std::string& line :
       {"size        " + std::to_string(fs::file_size(file)) + " bytes", std::string("profile x-stampscan, library stampscan 0.1"),
        std::string("channels    2"), std::string("/cmm/position"), std::string("schema stampscan_msgs/CmmPosition"),
        std::string("encoding cdr"), std::string("     100 messages"), std::string("/laser/profile"),
        std::string("      20 messages"), std::string("100.00 Hz"), std::string("20.00 Hz"),
        std::string("1700000000.000000000 .. 1700000000.990000000 s"), std::string("(0.990 s), 120 messages"),
        std::string("(zstd)"), std::string("ratio"), std::string("cell.yaml (text/yaml, 300 B)"),
        std::string("scan (1 keys)"), std::string("health      ok")})
    EXPECT_TRUE(contains(r.out, line)) << "missing: " << line << "\n" << r.out;
  EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST_F(StationTest, TraceInfoReportsACutTrace) {
  const fs::path file = writeTrace(work() / "scan.mcap");
  std::string bytes = readFile(file);
  bytes.resize(bytes.size() / 2);
  writeFile(work() / "cut.mcap", bytes);
  const RunResult r = run("trace info " + quote(work() / "cut.mcap"));
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_TRUE(contains(r.out, "TRUNCATED")) << r.out;
  EXPECT_TRUE(contains(r.out, "the file ends at byte " + std::to_string(bytes.size()))) << r.out;
  EXPECT_TRUE(contains(r.out, "recovered")) << r.out;
  EXPECT_TRUE(contains(r.out, "/cmm/position")) << r.out;
}

TEST_F(StationTest, TraceInfoReportsADamagedTrace) {
  const fs::path file = writeTrace(work() / "scan.mcap");
  std::string bytes = readFile(file);
  bytes[bytes.size() / 3] = static_cast<char>(bytes[bytes.size() / 3] ^ 0x40);
  writeFile(work() / "bad.mcap", bytes);
  const RunResult r = run("trace info " + quote(work() / "bad.mcap"));
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_TRUE(contains(r.out, "DAMAGED")) << r.out;
  EXPECT_TRUE(contains(r.out, "damage      at byte ")) << r.out;
}

TEST_F(StationTest, TraceInfoRejectsMissingAndForeignFiles) {
  const fs::path missing = work() / "missing.mcap";
  RunResult r = run("trace info " + quote(missing));
  expectCleanFailure(r, "missing.mcap");
  EXPECT_EQ(r.exit_code, 1);
  const fs::path ply = sample(2000, "scan.ply");
  r = run("trace info " + quote(ply));
  expectCleanFailure(r, "scan.ply");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, "not an MCAP file")) << r.err;
  writeFile(work() / "empty.mcap", "");
  r = run("trace info " + quote(work() / "empty.mcap"));
  expectCleanFailure(r, "empty.mcap");
}

TEST_F(StationTest, TraceHelpListsInfo) {
  const RunResult r = run("trace --help");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "info")) << r.out;
}

}  // namespace
}  // namespace stampscan::station::test
