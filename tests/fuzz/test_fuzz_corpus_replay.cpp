// Replays the fuzz entry functions over a fixed, seeded set of mutations of the seed corpus, so that
// builds without libFuzzer (GCC) still run the parsers on hostile input in CI. Every case must end
// in a parsed result or an InputError (for MCAP traces: a consistent damage report); the entry
// functions throw anything else, which fails here.
#include "fuzz_targets.hpp"
#include "mutation_replay.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::fuzz {
namespace {

namespace fs = std::filesystem;
using Target = int (*)(const std::uint8_t*, std::size_t);

std::vector<std::string> loadSeeds(const std::string& folder) {
  return loadSeedFiles(fs::path(STAMPSCAN_FUZZ_CORPUS_DIR) / folder);
}

std::string printable(const std::string& input) {
  std::string out;
  for (const char c : input.substr(0, 400)) {
    const auto u = static_cast<unsigned char>(c);
    if (u == '\n' || (u >= 0x20 && u < 0x7f)) {
      out += c;
    } else {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[u >> 4];
      out += kHex[u & 0xf];
    }
  }
  return out;
}

// Runs every prefix of every seed, then `mutationsPerSeed` mutations of each. Returns the case count.
std::size_t replay(Target target, const std::vector<std::string>& seeds, const std::vector<std::string>& donors,
                   std::size_t mutationsPerSeed, std::uint64_t generatorSeed) {
  std::size_t cases = 0;
  const auto run = [&](const std::string& input, const char* kind) {
    ++cases;
    try {
      target(reinterpret_cast<const std::uint8_t*>(input.data()), input.size());
    } catch (const std::exception& e) {
      ADD_FAILURE() << kind << " case " << cases << ": " << e.what() << "\ninput (" << input.size()
                    << " bytes):\n" << printable(input);
    }
  };
  for (const std::string& seed : seeds) {
    for (std::size_t length = 0; length <= seed.size(); ++length) run(seed.substr(0, length), "truncation");
  }
  Mutator mutator(generatorSeed);
  for (const std::string& seed : seeds) {
    for (std::size_t i = 0; i < mutationsPerSeed; ++i) run(mutator.mutate(seed, donors), "mutation");
  }
  return cases;
}

TEST(FuzzCorpusReplay, PlyReader) {
  const std::vector<std::string> seeds = loadSeeds("ply");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/ply";
  std::vector<std::string> donors = seeds;
  for (const std::string& text : loadSeeds("text")) donors.push_back(text);
  const std::size_t cases = replay(&fuzzPly, seeds, donors, 2000, 20240501);
  EXPECT_GT(cases, 8000u);
  RecordProperty("cases", static_cast<int>(cases));
}

TEST(FuzzCorpusReplay, TextReader) {
  const std::vector<std::string> seeds = loadSeeds("text");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/text";
  std::vector<std::string> donors = seeds;
  for (const std::string& ply : loadSeeds("ply")) donors.push_back(ply);
  const std::size_t cases = replay(&fuzzText, seeds, donors, 1500, 20240502);
  EXPECT_GT(cases, 6000u);
  RecordProperty("cases", static_cast<int>(cases));
}

TEST(FuzzCorpusReplay, StlReader) {
  const std::vector<std::string> seeds = loadSeeds("stl");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/stl";
  std::vector<std::string> donors = seeds;
  for (const std::string& ply : loadSeeds("ply")) donors.push_back(ply);
  const std::size_t cases = replay(&fuzzStl, seeds, donors, 2000, 20240508);
  EXPECT_GT(cases, 8000u);
  RecordProperty("cases", static_cast<int>(cases));
}

TEST(FuzzCorpusReplay, McapReader) {
  const std::vector<std::string> seeds = loadSeeds("mcap");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/mcap";
  const std::size_t cases = replay(&fuzzMcap, seeds, seeds, 4000, 20240503);
  EXPECT_GT(cases, 20000u);
  RecordProperty("cases", static_cast<int>(cases));
}

// Network input. The session runs each command (moves take milliseconds), so fewer cases here.
TEST(FuzzCorpusReplay, IppServerLines) {
  const std::vector<std::string> seeds = loadSeeds("ipp_server");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/ipp_server";
  const std::size_t cases = replay(&fuzzIppServer, seeds, seeds, 300, 20240504);
  EXPECT_GT(cases, 1000u);
  RecordProperty("cases", static_cast<int>(cases));
}

TEST(FuzzCorpusReplay, IppClientReplies) {
  const std::vector<std::string> seeds = loadSeeds("ipp_client");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/ipp_client";
  std::vector<std::string> donors = seeds;
  for (const std::string& commands : loadSeeds("ipp_server")) donors.push_back(commands);
  const std::size_t cases = replay(&fuzzIppClient, seeds, donors, 3000, 20240505);
  EXPECT_GT(cases, 3000u);
  RecordProperty("cases", static_cast<int>(cases));
}

TEST(FuzzCorpusReplay, ModbusRequests) {
  const std::vector<std::string> seeds = loadSeeds("modbus");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/modbus";
  const std::size_t cases = replay(&fuzzModbus, seeds, seeds, 1000, 20240506);
  EXPECT_GT(cases, 9000u);
  RecordProperty("cases", static_cast<int>(cases));
}

// Each case builds a fresh camera model (cheap: a few microseconds).
TEST(FuzzCorpusReplay, GvcpRequests) {
  const std::vector<std::string> seeds = loadSeeds("gvcp");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/gvcp";
  const std::size_t cases = replay(&fuzzGvcp, seeds, seeds, 4000, 20240507);
  EXPECT_GT(cases, 20000u);
  RecordProperty("cases", static_cast<int>(cases));
}

}  // namespace
}  // namespace stampscan::fuzz
