// The I++ DME fuzz entry function, shared by the libFuzzer target (Clang) and the seeded replay in
// the GoogleTest suite. Returns 0 when every line either parsed into something that formats and
// parses back to the same value, or was rejected with a well-formed ProtocolError; anything else
// (another exception, a broken invariant, a crash) is a bug.
#pragma once

#include <cstddef>
#include <cstdint>

namespace stampscan::fuzz {

int fuzzIpp(const std::uint8_t* data, std::size_t size);

}  // namespace stampscan::fuzz
