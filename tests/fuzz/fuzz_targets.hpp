// The fuzz entry functions, shared by the libFuzzer targets (Clang) and the corpus replay test.
// Each returns 0 when the input either parsed into a consistent result or was rejected with an
// InputError; anything else (another exception, a broken invariant, a crash) is a bug.
#pragma once

#include <cstddef>
#include <cstdint>

namespace stampscan::fuzz {

int fuzzPly(const std::uint8_t* data, std::size_t size);
int fuzzText(const std::uint8_t* data, std::size_t size);
// The STL reader of part programs' nominal models (a ModelError is the clean rejection).
int fuzzStl(const std::uint8_t* data, std::size_t size);
// The MCAP trace reader never throws on content; 0 always (failures throw std::logic_error).
int fuzzMcap(const std::uint8_t* data, std::size_t size);
// I++ DME lines: a client's bytes through the virtual CMM's session (every answer a well-formed line
// within the limit), and a server's bytes through the CMM driver's response reading.
int fuzzIppServer(const std::uint8_t* data, std::size_t size);
int fuzzIppClient(const std::uint8_t* data, std::size_t size);
// Modbus TCP requests through the virtual PLC's framing and verdicts, and libmodbus's reply.
int fuzzModbus(const std::uint8_t* data, std::size_t size);
// GVCP request datagrams through the virtual cameras' server (every answer a well-formed acknowledge).
int fuzzGvcp(const std::uint8_t* data, std::size_t size);

}  // namespace stampscan::fuzz
