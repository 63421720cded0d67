// How the virtual PLC reads Modbus TCP requests before libmodbus answers them: the byte stream cut
// into ADUs at their MBAP length, and a verdict on each ADU. Pure (no sockets, no libmodbus), so
// that the fuzz targets can feed it any bytes.
//
// References: "MODBUS Messaging on TCP/IP Implementation Guide V1.0b" (the MBAP header: transaction
// id, protocol id 0 for Modbus, length of what follows, unit id) and "MODBUS Application Protocol
// Specification V1.1b3" (function codes, exception codes).
//
// Which requests are answered (documented for clients in drivers/plc/REGISTER_MAP.md):
// - protocol id other than 0: not Modbus; dropped without an answer, as the implementation guide
//   asks of a server. The connection stays usable (the MBAP length still frames the stream).
// - unit id: the PLC's own (VirtualPlcOptions::unit_id, the cell config's plc.unit_id) and 0xFF,
//   the value the guide gives for addressing a TCP device itself. Any other unit, 0 included (a
//   serial-line broadcast, meaningless on a TCP link), gets exception 0x0B "gateway target device
//   failed to respond": a client with a wrong unit id learns so at once instead of timing out.
// - function codes of the register map (01-06, 0F, 10) with a PDU of the right length are served
//   (libmodbus then checks addresses and counts); other codes get 0x01 "illegal function", a PDU of
//   the wrong length 0x03 "illegal data value". Only served ADUs reach libmodbus, which trusts its
//   input to be framed consistently.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace stampscan::sim::detail {

inline constexpr std::size_t kMbapHeaderLength = 7;  // transaction id 2, protocol id 2, length 2, unit id 1
inline constexpr std::size_t kMaxAduLength = 260;    // MBAP header + the largest PDU (253 bytes)
inline constexpr std::uint8_t kUnitIdItself = 0xFF;  // "this device" on TCP

inline constexpr std::uint8_t kIllegalFunction = 0x01;
inline constexpr std::uint8_t kIllegalDataValue = 0x03;
inline constexpr std::uint8_t kGatewayTargetFailed = 0x0B;

struct MbapHeader {
  std::uint16_t transaction_id = 0;
  std::uint16_t protocol_id = 0;
  std::uint16_t length = 0;  // bytes after the length field: unit id and PDU
  std::uint8_t unit_id = 0;
};

// The header at the start of `bytes`, if there are 7 bytes.
std::optional<MbapHeader> parseMbapHeader(std::span<const std::uint8_t> bytes);

// Cuts a byte stream into ADUs. A length field outside 2..254 (no function code, or more than the
// largest ADU) cannot be framed past: the stream is broken and the connection must close.
class ModbusTcpFramer {
 public:
  void append(std::span<const std::uint8_t> bytes);
  std::optional<std::vector<std::uint8_t>> next();
  bool broken() const { return broken_; }
  // Bytes of an ADU that has begun but not ended.
  std::size_t pendingBytes() const { return buffer_.size() - start_; }

 private:
  std::vector<std::uint8_t> buffer_;
  std::size_t start_ = 0;  // buffer_[start_..] is not consumed yet
  bool broken_ = false;
};

enum class RequestAction { Serve, Drop, Refuse };

struct RequestVerdict {
  RequestAction action = RequestAction::Drop;
  std::uint8_t exception_code = 0;  // Refuse
  std::string reason;               // Drop and Refuse: why, for a log or a test
};

// What to do with one ADU for the PLC with unit id `unit_id` (see the file comment).
RequestVerdict checkRequest(std::span<const std::uint8_t> adu, std::uint8_t unit_id);

// The exception response to `adu` (which checkRequest refused): its transaction and unit id, the
// function code with the high bit set, and `exception_code`. Empty when `adu` has no function code.
std::vector<std::uint8_t> exceptionResponse(std::span<const std::uint8_t> adu, std::uint8_t exception_code);

}  // namespace stampscan::sim::detail
