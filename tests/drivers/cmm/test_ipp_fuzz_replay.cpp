// Replays the I++ DME fuzz entry function over every prefix of the seed corpus and a fixed, seeded
// set of mutations of it, so that GCC builds (no libFuzzer) run the parsers on hostile input too.
#include "fuzz_ipp.hpp"
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

std::vector<std::string> loadSeeds() { return loadSeedFiles(STAMPSCAN_IPP_CORPUS_DIR); }

// Grammar tokens of I++ DME lines: delimiters, tags, numbers at the limits.
MutatorOptions ippMutations() {
  return {{"(", ")", ",", " ", "\"", ".", "E", "e", "\r", "\n", "\r\n", "E0000", "00000", "99999", "1e999", "-."}, 20};
}

TEST(IppFuzzReplay, ParsersSurviveMutatedLines) {
  const std::vector<std::string> seeds = loadSeeds();
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_IPP_CORPUS_DIR;
  std::size_t cases = 0;
  const auto run = [&](const std::string& input) {
    ++cases;
    try {
      fuzzIpp(reinterpret_cast<const std::uint8_t*>(input.data()), input.size());
    } catch (const std::exception& e) {
      ADD_FAILURE() << "case " << cases << ": " << e.what() << "\ninput: " << input.substr(0, 300);
    }
  };
  for (const std::string& seed : seeds) {
    for (std::size_t length = 0; length <= seed.size(); ++length) run(seed.substr(0, length));
  }
  Mutator mutator(20240601, ippMutations());
  for (const std::string& seed : seeds) {
    for (int i = 0; i < 3000; ++i) run(mutator.mutate(seed, seeds));
  }
  EXPECT_GT(cases, 12000u);
  RecordProperty("cases", static_cast<int>(cases));
}

}  // namespace
}  // namespace stampscan::fuzz
