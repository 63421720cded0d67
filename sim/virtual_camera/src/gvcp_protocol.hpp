// The GigE Vision wire constants the virtual cameras serve (GigE Vision 2.0: GVCP chapter for the
// control channel, bootstrap register map, GVSP chapter for the stream), and big-endian field
// access over byte spans. Everything on the wire is big endian ("network order").
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace stampscan::sim::gvcp {

inline constexpr std::uint16_t kPort = 3956;  // the GVCP UDP port of every GigE Vision device

// GVCP header: a command is key(8) flags(8) command(16) length(16) req_id(16); an acknowledge is
// status(16) answer(16) length(16) ack_id(16). `length` counts the bytes after the header.
inline constexpr std::size_t kHeaderSize = 8;
inline constexpr std::uint8_t kCommandKey = 0x42;
inline constexpr std::uint8_t kFlagAcknowledge = 0x01;  // the sender wants an acknowledge
// The largest GVCP payload (a 576-byte datagram minus IP, UDP and GVCP headers) and so the largest
// READMEM/WRITEMEM data block: 540 = 4 bytes of address + 536 bytes of data.
inline constexpr std::size_t kMaxPayload = 540;
inline constexpr std::uint32_t kMaxMemoryBlock = 536;

// Command and acknowledge codes.
inline constexpr std::uint16_t DISCOVERY_CMD = 0x0002, DISCOVERY_ACK = 0x0003;
inline constexpr std::uint16_t PACKETRESEND_CMD = 0x0040;  // never acknowledged
inline constexpr std::uint16_t READREG_CMD = 0x0080, READREG_ACK = 0x0081;
inline constexpr std::uint16_t WRITEREG_CMD = 0x0082, WRITEREG_ACK = 0x0083;
inline constexpr std::uint16_t READMEM_CMD = 0x0084, READMEM_ACK = 0x0085;
inline constexpr std::uint16_t WRITEMEM_CMD = 0x0086, WRITEMEM_ACK = 0x0087;

// Status codes of an acknowledge.
enum Status : std::uint16_t {
  GEV_STATUS_SUCCESS = 0x0000,
  GEV_STATUS_NOT_IMPLEMENTED = 0x8001,    // command not supported
  GEV_STATUS_INVALID_PARAMETER = 0x8002,  // a count or field out of its range
  GEV_STATUS_INVALID_ADDRESS = 0x8003,    // address outside the device's register/memory space
  GEV_STATUS_WRITE_PROTECT = 0x8004,      // a read-only register
  GEV_STATUS_BAD_ALIGNMENT = 0x8005,      // address or count not a multiple of 4
  GEV_STATUS_ACCESS_DENIED = 0x8006,      // another application holds the control channel
  GEV_STATUS_INVALID_HEADER = 0x800E,     // the header's length disagrees with the datagram
};

// Bootstrap registers (GigE Vision bootstrap register map).
inline constexpr std::uint32_t kRegVersion = 0x0000;
inline constexpr std::uint32_t kRegMacHigh = 0x0008, kRegMacLow = 0x000C;
inline constexpr std::uint32_t kDiscoveryDataSize = 0x00F8;  // a DISCOVERY_ACK carries 0x0000-0x00F7
inline constexpr std::uint32_t kRegXmlUrl0 = 0x0200;         // "Local:name;address;size", 512 bytes
inline constexpr std::uint32_t kRegHeartbeatTimeout = 0x0938;  // ms
inline constexpr std::uint32_t kRegTimestampControl = 0x0944;  // write kTimestampLatch to latch the counter
inline constexpr std::uint32_t kRegTimestampValueHigh = 0x0948, kRegTimestampValueLow = 0x094C;  // the latched value
inline constexpr std::uint32_t kTimestampLatch = 0x2;
inline constexpr std::uint32_t kRegControlChannelPrivilege = 0x0A00;  // CCP
inline constexpr std::uint32_t kRegStreamHostPort = 0x0D00;   // SCP0: host port in bits 15..0
inline constexpr std::uint32_t kRegStreamPacketSize = 0x0D04; // SCPS0: packet size in bits 15..0
inline constexpr std::uint32_t kRegStreamDestination = 0x0D18;  // SCDA0: host IPv4 address
inline constexpr std::uint32_t kRegStreamSourcePort = 0x0D1C;   // SCSP0: the device's source port

// CCP bits (bit numbers counted from the least significant bit).
inline constexpr std::uint32_t kCcpExclusive = 0x1, kCcpControl = 0x2;
inline constexpr std::uint32_t kMinHeartbeatTimeoutMs = 500;  // the spec's smallest heartbeat timeout

// GVSP: header status(16) block_id(16) EI(1)|reserved(3)|format(4) packet_id(24).
inline constexpr std::size_t kGvspHeaderSize = 8;
inline constexpr std::uint8_t kGvspLeader = 0x01, kGvspTrailer = 0x02, kGvspPayload = 0x03;
inline constexpr std::uint16_t kGvspPayloadTypeImage = 0x0001;
// What GevSCPSPacketSize counts beyond the GVSP data: IPv4 (20) + UDP (8) + GVSP header (8).
inline constexpr std::uint32_t kGvspPacketOverhead = 36;

inline std::uint16_t readBe16(std::span<const std::uint8_t> bytes, std::size_t at) {
  return static_cast<std::uint16_t>((bytes[at] << 8) | bytes[at + 1]);
}

inline std::uint32_t readBe32(std::span<const std::uint8_t> bytes, std::size_t at) {
  return (std::uint32_t{bytes[at]} << 24) | (std::uint32_t{bytes[at + 1]} << 16) |
         (std::uint32_t{bytes[at + 2]} << 8) | std::uint32_t{bytes[at + 3]};
}

inline void writeBe16(std::span<std::uint8_t> bytes, std::size_t at, std::uint16_t value) {
  bytes[at] = static_cast<std::uint8_t>(value >> 8);
  bytes[at + 1] = static_cast<std::uint8_t>(value);
}

inline void writeBe32(std::span<std::uint8_t> bytes, std::size_t at, std::uint32_t value) {
  writeBe16(bytes, at, static_cast<std::uint16_t>(value >> 16));
  writeBe16(bytes, at + 2, static_cast<std::uint16_t>(value));
}

}  // namespace stampscan::sim::gvcp
