// Replays the I++ DME fuzz entry function over every prefix of the seed corpus and a fixed, seeded
// set of mutations of it, so that GCC builds (no libFuzzer) run the parsers on hostile input too.
#include "fuzz_ipp.hpp"

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

std::vector<std::string> loadSeeds() {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(STAMPSCAN_IPP_CORPUS_DIR)) {
    if (entry.is_regular_file()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());  // directory order varies; the case list must not
  std::vector<std::string> seeds;
  for (const fs::path& file : files) {
    std::ifstream in(file, std::ios::binary);
    seeds.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  return seeds;
}

// Byte-level mutations plus ones aimed at the grammar (delimiters, tags, numbers). Only the raw
// output of a fixed-seed generator is used, so the cases are the same with every standard library.
class Mutator {
 public:
  explicit Mutator(std::uint64_t seed) : random_(seed) {}

  std::string mutate(std::string input, const std::vector<std::string>& donors) {
    static constexpr std::array<std::string_view, 16> kTokens{
        "(", ")", ",", " ", "\"", ".", "E", "e", "\r", "\n", "\r\n", "E0000", "00000", "99999", "1e999", "-."};
    const std::size_t rounds = 1 + below(4);
    for (std::size_t round = 0; round < rounds; ++round) {
      switch (below(7)) {
        case 0:
          if (!input.empty()) input[below(input.size())] ^= static_cast<char>(1 << below(8));
          break;
        case 1:
          if (!input.empty()) input[below(input.size())] = static_cast<char>(below(256));
          break;
        case 2:
          input.resize(below(input.size() + 1));
          break;
        case 3: {
          const std::string_view token = kTokens[below(kTokens.size())];
          input.insert(below(input.size() + 1), token);
          break;
        }
        case 4: {
          const std::string& donor = donors[below(donors.size())];
          const std::size_t start = below(donor.size() + 1);
          input.insert(below(input.size() + 1), donor.substr(start, below(donor.size() - start + 1)));
          break;
        }
        case 5: {
          const std::size_t start = below(input.size() + 1);
          input.erase(start, below(input.size() - start + 1));
          break;
        }
        default: {  // repeat a range, e.g. into deep nesting or long numbers
          const std::size_t start = below(input.size() + 1);
          const std::string part = input.substr(start, below(std::min<std::size_t>(input.size() - start, 32) + 1));
          for (std::size_t i = below(20); i > 0; --i) input.insert(start, part);
          break;
        }
      }
    }
    return input;
  }

 private:
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(random_() % n); }
  std::mt19937_64 random_;
};

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
  Mutator mutator(20240601);
  for (const std::string& seed : seeds) {
    for (int i = 0; i < 3000; ++i) run(mutator.mutate(seed, seeds));
  }
  EXPECT_GT(cases, 12000u);
  RecordProperty("cases", static_cast<int>(cases));
}

}  // namespace
}  // namespace stampscan::fuzz
