// Seeded mutation replay, shared by the GoogleTest suites that run the fuzz targets without
// libFuzzer: the seed files of a corpus folder, and a mutator in the spirit of libFuzzer's. Only the
// raw output of a fixed-seed generator is used (no std distributions), so the cases are the same
// with every standard library, and a failing case replays.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::fuzz {

// The files of a corpus folder, in name order (directory order varies; the case list must not).
inline std::vector<std::string> loadSeedFiles(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    if (entry.is_regular_file()) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  std::vector<std::string> seeds;
  for (const auto& file : files) {
    std::ifstream in(file, std::ios::binary);
    seeds.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  return seeds;
}

struct MutatorOptions {
  // Grammar tokens to insert (delimiters, tags, keywords); empty: random bytes instead.
  std::vector<std::string_view> tokens;
  // A repeated range is inserted up to this many times (deep nesting, long numbers).
  std::size_t max_repeats = 1;
};

class Mutator {
 public:
  explicit Mutator(std::uint64_t seed, MutatorOptions options = {}) : random_(seed), options_(std::move(options)) {}

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
        case 3:  // insert a token of the grammar, or a few random bytes
          if (!options_.tokens.empty()) {
            input.insert(below(input.size() + 1), options_.tokens[below(options_.tokens.size())]);
          } else {
            std::string bytes(1 + below(8), '\0');
            for (char& c : bytes) c = static_cast<char>(below(256));
            input.insert(below(input.size() + 1), bytes);
          }
          break;
        case 4: {  // insert a slice of another seed
          if (donors.empty()) break;
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
          for (std::size_t i = 1 + below(options_.max_repeats); i > 0; --i) input.insert(start, part);
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
  MutatorOptions options_;
};

}  // namespace stampscan::fuzz
