// Replays the fuzz entry functions over a fixed, seeded set of mutations of the seed corpus, so that
// builds without libFuzzer (GCC) still run the parsers on hostile input in CI. Every case must end
// in a parsed result or an InputError (for MCAP traces: a consistent damage report); the entry
// functions throw anything else, which fails here.
#include "fuzz_targets.hpp"

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
  const fs::path dir = fs::path(STAMPSCAN_FUZZ_CORPUS_DIR) / folder;
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
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

// Mutations in the spirit of libFuzzer's, drawn from a fixed-seed generator. Only the generator's
// raw output is used (no std distributions), so the cases are the same with every standard library.
class Mutator {
 public:
  explicit Mutator(std::uint64_t seed) : random_(seed) {}

  std::string mutate(std::string input, const std::vector<std::string>& donors) {
    const std::size_t rounds = 1 + below(4);
    for (std::size_t round = 0; round < rounds; ++round) {
      switch (below(8)) {
        case 0:  // flip one bit
          if (!input.empty()) input[below(input.size())] ^= static_cast<char>(1 << below(8));
          break;
        case 1:  // overwrite one byte
          if (!input.empty()) input[below(input.size())] = static_cast<char>(below(256));
          break;
        case 2:  // truncate
          input.resize(below(input.size() + 1));
          break;
        case 3: {  // insert a few random bytes
          std::string bytes(1 + below(8), '\0');
          for (char& c : bytes) c = static_cast<char>(below(256));
          input.insert(below(input.size() + 1), bytes);
          break;
        }
        case 4: {  // insert a slice of another seed
          const std::string& donor = donors[below(donors.size())];
          const std::size_t start = below(donor.size() + 1);
          input.insert(below(input.size() + 1), donor.substr(start, below(donor.size() - start + 1)));
          break;
        }
        case 5: {  // erase a range
          const std::size_t start = below(input.size() + 1);
          input.erase(start, below(input.size() - start + 1));
          break;
        }
        case 6:  // replace a number by one that stresses counts and conversions
          replaceNumber(input);
          break;
        default: {  // repeat a range
          const std::size_t start = below(input.size() + 1);
          const std::string part = input.substr(start, below(std::min<std::size_t>(input.size() - start, 64) + 1));
          input.insert(start, part);
          break;
        }
      }
    }
    return input;
  }

 private:
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(random_() % n); }

  void replaceNumber(std::string& input) {
    static constexpr std::array<std::string_view, 12> kValues{
        "0", "-1", "255", "65535", "4294967295", "4294967296", "18446744073709551615", "1e309", "nan", "-inf",
        "99999999999", "0.5"};
    if (input.empty()) return;
    std::size_t pos = below(input.size());
    while (pos < input.size() && (input[pos] < '0' || input[pos] > '9')) ++pos;
    if (pos == input.size()) return;
    std::size_t end = pos;
    while (end < input.size() && input[end] >= '0' && input[end] <= '9') ++end;
    input.replace(pos, end - pos, kValues[below(kValues.size())]);
  }

  std::mt19937_64 random_;
};

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

TEST(FuzzCorpusReplay, McapReader) {
  const std::vector<std::string> seeds = loadSeeds("mcap");
  ASSERT_FALSE(seeds.empty()) << "no seeds in " << STAMPSCAN_FUZZ_CORPUS_DIR << "/mcap";
  const std::size_t cases = replay(&fuzzMcap, seeds, seeds, 4000, 20240503);
  EXPECT_GT(cases, 20000u);
  RecordProperty("cases", static_cast<int>(cases));
}

}  // namespace
}  // namespace stampscan::fuzz
