// The fuzz entry functions, shared by the libFuzzer targets (Clang) and the corpus replay test.
// Each returns 0 when the input either parsed into a consistent result or was rejected with an
// InputError; anything else (another exception, a broken invariant, a crash) is a bug.
#pragma once

#include <cstddef>
#include <cstdint>

namespace stampscan::fuzz {

int fuzzPly(const std::uint8_t* data, std::size_t size);
int fuzzText(const std::uint8_t* data, std::size_t size);
// The MCAP trace reader never throws on content; 0 always (failures throw std::logic_error).
int fuzzMcap(const std::uint8_t* data, std::size_t size);

}  // namespace stampscan::fuzz
