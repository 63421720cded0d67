#include "modbus_frame.hpp"

namespace stampscan::sim::detail {

namespace {

constexpr std::size_t kMinLengthField = 2;                                   // unit id + function code
constexpr std::size_t kMaxLengthField = kMaxAduLength - kMbapHeaderLength + 1;  // 254

std::uint16_t bigEndian(std::span<const std::uint8_t> bytes, std::size_t at) {
  return static_cast<std::uint16_t>((bytes[at] << 8) | bytes[at + 1]);
}

// The PDU length a served function code needs, given the PDU (function code first); 0 when the PDU
// is too short to tell.
std::size_t expectedPduLength(std::span<const std::uint8_t> pdu) {
  switch (pdu[0]) {
    case 0x01:  // read coils
    case 0x02:  // read discrete inputs
    case 0x03:  // read holding registers
    case 0x04:  // read input registers
    case 0x05:  // write single coil
    case 0x06:  // write single register
      return 5;  // function, address, count or value
    case 0x0F:  // write multiple coils
    case 0x10:  // write multiple registers: function, address, count, byte count, the bytes
      return pdu.size() < 6 ? 0 : 6 + std::size_t{pdu[5]};
    default:
      return 0;
  }
}

bool served(std::uint8_t function) {
  return (function >= 0x01 && function <= 0x06) || function == 0x0F || function == 0x10;
}

}  // namespace

std::optional<MbapHeader> parseMbapHeader(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kMbapHeaderLength) return std::nullopt;
  return MbapHeader{bigEndian(bytes, 0), bigEndian(bytes, 2), bigEndian(bytes, 4), bytes[6]};
}

void ModbusTcpFramer::append(std::span<const std::uint8_t> bytes) {
  if (broken_) return;
  if (start_ > 0) {  // drop what next() consumed before growing the buffer
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start_));
    start_ = 0;
  }
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

std::optional<std::vector<std::uint8_t>> ModbusTcpFramer::next() {
  if (broken_) return std::nullopt;
  const std::span<const std::uint8_t> rest = std::span<const std::uint8_t>(buffer_).subspan(start_);
  const std::optional<MbapHeader> header = parseMbapHeader(rest);
  if (!header) return std::nullopt;
  if (header->length < kMinLengthField || header->length > kMaxLengthField) {
    broken_ = true;  // where the next ADU starts is unknown
    buffer_.clear();
    start_ = 0;
    return std::nullopt;
  }
  const std::size_t size = kMbapHeaderLength - 1 + header->length;
  if (rest.size() < size) return std::nullopt;
  std::vector<std::uint8_t> adu(rest.begin(), rest.begin() + static_cast<std::ptrdiff_t>(size));
  start_ += size;
  return adu;
}

RequestVerdict checkRequest(std::span<const std::uint8_t> adu, std::uint8_t unit_id) {
  const std::optional<MbapHeader> header = parseMbapHeader(adu);
  if (!header || adu.size() < kMbapHeaderLength + 1) return {RequestAction::Drop, 0, "shorter than an MBAP header and a function code"};
  if (header->length != adu.size() - (kMbapHeaderLength - 1))
    return {RequestAction::Drop, 0, "the MBAP length does not match the frame"};
  if (header->protocol_id != 0)
    return {RequestAction::Drop, 0, "protocol id " + std::to_string(header->protocol_id) + " is not Modbus (0)"};
  if (header->unit_id != unit_id && header->unit_id != kUnitIdItself)
    return {RequestAction::Refuse, kGatewayTargetFailed,
            "unit id " + std::to_string(header->unit_id) + " is not this PLC's (" + std::to_string(unit_id) + ")"};
  const std::span<const std::uint8_t> pdu = adu.subspan(kMbapHeaderLength);
  if (!served(pdu[0]))
    return {RequestAction::Refuse, kIllegalFunction, "function code " + std::to_string(pdu[0]) + " is not served"};
  if (pdu.size() != expectedPduLength(pdu))
    return {RequestAction::Refuse, kIllegalDataValue,
            "a PDU of " + std::to_string(pdu.size()) + " bytes for function code " + std::to_string(pdu[0])};
  return {RequestAction::Serve, 0, {}};
}

std::vector<std::uint8_t> exceptionResponse(std::span<const std::uint8_t> adu, std::uint8_t exception_code) {
  if (adu.size() < kMbapHeaderLength + 1) return {};
  // Transaction id as asked, protocol id 0, length 3 (unit, function, code), unit id as asked.
  return {adu[0], adu[1], 0, 0, 0, 3, adu[6], static_cast<std::uint8_t>(adu[7] | 0x80), exception_code};
}

}  // namespace stampscan::sim::detail
