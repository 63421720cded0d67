// Shared by the trace tests: deterministic payloads, writing a trace from a list of messages, and
// reading every message back with its health report.
#pragma once

#include "stampscan/acquisition/trace/mcap_reader.hpp"
#include "stampscan/acquisition/trace/mcap_writer.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <system_error>
#include <vector>

namespace stampscan::trace::test {

namespace fs = std::filesystem;

struct Msg {
  std::uint16_t channel = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0, publish_time = 0;
  std::vector<std::byte> data;
  bool verified = false;  // as read back
  bool operator==(const Msg& o) const {
    return channel == o.channel && sequence == o.sequence && log_time == o.log_time && publish_time == o.publish_time &&
           data == o.data;
  }
};

inline std::ostream& operator<<(std::ostream& os, const Msg& m) {
  return os << "{channel " << m.channel << ", seq " << m.sequence << ", t " << m.log_time << ", " << m.data.size()
            << " bytes}";
}

// Compressible (so zstd chunks stay compressed) but different for every seed.
inline std::vector<std::byte> payload(std::uint64_t seed, std::size_t size) {
  std::vector<std::byte> out(size);
  std::mt19937_64 random(seed);
  const std::uint64_t word = random();
  for (std::size_t i = 0; i < size; ++i)
    out[i] = static_cast<std::byte>(i % 16 < 12 ? (word >> (8 * (i % 8))) & 0xFF : random() & 0xFF);
  return out;
}

inline std::vector<std::byte> readBytes(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::vector<char> chars{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  std::vector<std::byte> out(chars.size());
  for (std::size_t i = 0; i < chars.size(); ++i) out[i] = static_cast<std::byte>(chars[i]);
  return out;
}

inline void writeBytes(const fs::path& file, std::span<const std::byte> bytes) {
  std::ofstream out(file, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

struct ReadBack {
  std::vector<Msg> messages;
  TraceHealth health;
};

inline ReadBack readAll(McapReader& reader, const ReadOptions& options = {}) {
  ReadBack r;
  r.health = reader.readMessages(
      [&](const TraceMessage& m) {
        r.messages.push_back({m.channel_id, m.sequence, m.log_time, m.publish_time,
                              std::vector<std::byte>(m.data.begin(), m.data.end()), m.verified});
        return true;
      },
      options);
  return r;
}

inline ReadBack readAll(std::span<const std::byte> bytes, const ReadOptions& options = {}) {
  McapReader reader(bytes, "memory");
  return readAll(reader, options);
}

// Names the cases of a test parameterised on compression: none, zstd, lz4.
inline std::string compressionCase(const ::testing::TestParamInfo<Compression>& p) {
  return p.param == Compression::None ? std::string("none") : compressionName(p.param);
}

// A scratch folder per test, removed afterwards.
class TraceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device device;
    dir_ = fs::temp_directory_path() / ("stampscan_trace_test_" + std::to_string(device()) + std::to_string(device()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
};

// The small trace of the truncation and damage tests: 3 channels, 40 messages over 2 s, chunks of
// about 1 KiB, one metadata record and one attachment between the chunks.
inline std::vector<Msg> writeSmallTrace(const fs::path& file, Compression compression) {
  McapWriterOptions options;
  options.compression = compression;
  options.chunk_size = 1024;
  McapWriter writer(file, options);
  const std::uint16_t schema = writer.addSchema("stampscan.Test", "jsonschema", std::string_view(R"({"type":"object"})"));
  const std::uint16_t channels[3] = {writer.addChannel(schema, "/cmm/position", "json", {{"device", "cmm"}}),
                                     writer.addChannel(schema, "/laser/profile", "json", {}),
                                     writer.addChannel(0, "/plc/state", "json", {{"rate", "10"}})};
  std::vector<Msg> written;
  std::uint32_t sequence[3] = {0, 0, 0};
  for (std::uint32_t i = 0; i < 40; ++i) {
    const std::size_t c = i % 3;
    Msg m{channels[c], sequence[c]++, 1'000'000'000 + i * 50'000'000ull, 2'000'000'000 + i, payload(i, 40 + (i * 37) % 120), false};
    writer.write(m.channel, m.log_time, m.publish_time, m.data);
    written.push_back(std::move(m));
    if (i == 15) writer.addMetadata("scan", {{"part", "pan-1"}, {"operator", "test"}});
    if (i == 25) writer.addAttachment("calibration.yaml", "text/yaml", 1'500'000'000, payload(99, 64));
  }
  writer.close();
  return written;
}

}  // namespace stampscan::trace::test
