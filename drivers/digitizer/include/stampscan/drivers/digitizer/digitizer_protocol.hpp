// The laser digitizer's USB wire format (documented in drivers/digitizer/PROTOCOL.md), written once
// and shared by the UsbDigitizer driver and the virtual digitizer of sim/virtual_digitizer, so that
// the two cannot drift apart. Pure byte encoding: no libusb here.
//
// Every decoder checks lengths and ranges before it reads and throws ProtocolError naming the field
// that was wrong; it never reads past the span it was given.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::drivers::digitizer {

// 0x1d50 is the open-hardware vendor id (OpenMoko's block, shared out to open projects); 0x61a5 is
// the product id StampScan uses for its digitizer head. See PROTOCOL.md.
inline constexpr std::uint16_t kVendorId = 0x1d50;
inline constexpr std::uint16_t kProductId = 0x61a5;
inline constexpr int kInterface = 0;
inline constexpr std::uint8_t kProfileEndpoint = 0x81;  // bulk in

// bmRequestType of the vendor requests: vendor type, interface recipient, direction bit 7.
inline constexpr std::uint8_t kRequestTypeIn = 0xc1;
inline constexpr std::uint8_t kRequestTypeOut = 0x41;

enum class Request : std::uint8_t {
  GetIdentity = 0x01,  // in, IdentityPayload
  SetConfig = 0x02,    // out, kConfigSize bytes
  GetConfig = 0x03,    // in, kConfigReplySize bytes
  Start = 0x04,        // out, no data
  Stop = 0x05,         // out, no data
  GetStatus = 0x06,    // in, kStatusSize bytes
};
const char* toString(Request request);

inline constexpr std::uint16_t kProtocolVersion = 1;
inline constexpr std::size_t kMaxStringLength = 64;
inline constexpr std::size_t kIdentityMaxSize = 2 + 3 * (1 + kMaxStringLength);
inline constexpr std::size_t kConfigSize = 12;
inline constexpr std::size_t kConfigReplySize = 20;
inline constexpr std::size_t kStatusSize = 16;

inline constexpr std::uint32_t kProfileMagic = 0x504c5353;  // "SSLP" in the byte stream
inline constexpr std::size_t kProfileHeaderSize = 24;
inline constexpr std::size_t kPointSize = 6;  // float32 range + u16 intensity
inline constexpr int kMinPoints = 16;
inline constexpr int kMaxPoints = 4096;
inline constexpr double kMinProfileRateHz = 1, kMaxProfileRateHz = 20000;

// Status word bits, in the profile header and in GetStatus.
inline constexpr std::uint32_t kStatusOverexposed = 1u << 0;
inline constexpr std::uint32_t kStatusMirrorFault = 1u << 1;
inline constexpr std::uint32_t kStatusStreaming = 1u << 8;  // GetStatus only

class ProtocolError : public std::runtime_error {
 public:
  ProtocolError(std::string field, const std::string& what)
      : std::runtime_error("digitizer protocol: " + field + ": " + what), field_(std::move(field)) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

struct Identity {
  std::uint16_t protocol_version = kProtocolVersion;
  std::string model, serial, firmware;  // at most kMaxStringLength bytes each
  bool operator==(const Identity&) const = default;
};

struct DigitizerConfig {
  int points_per_profile = 1024;  // kMinPoints..kMaxPoints
  double profile_rate_hz = 500;   // sent in millihertz; 1 Hz .. 20 kHz
  std::uint32_t exposure_us = 200;  // 1 .. 1,000,000 / profile rate
  bool operator==(const DigitizerConfig&) const = default;
};
// Throws ProtocolError naming the field that is out of range.
void validate(const DigitizerConfig& config);

// GetConfig: the configuration in force and the fan geometry it implies.
struct ConfigReply {
  DigitizerConfig config;
  float angle_min = 0, angle_increment = 0;  // rad
  bool operator==(const ConfigReply&) const = default;
};

struct DeviceStatus {
  std::uint32_t status_word = 0;
  std::uint32_t next_sequence = 0;  // sequence number the next profile will carry
  std::uint64_t device_time_ns = 0;
  bool operator==(const DeviceStatus&) const = default;
};

// One profile as it travels on the bulk endpoint.
struct Profile {
  std::uint32_t sequence = 0;
  std::uint64_t device_time_ns = 0;  // digitizer clock
  std::uint32_t status = 0;
  std::vector<float> range;              // mm along the ray; 0 = no return
  std::vector<std::uint16_t> intensity;  // same length as range
  bool operator==(const Profile&) const = default;
};

using Bytes = std::vector<std::uint8_t>;
using ByteView = std::span<const std::uint8_t>;

Bytes encode(const Identity& identity);
Bytes encode(const DigitizerConfig& config);
Bytes encode(const ConfigReply& reply);
Bytes encode(const DeviceStatus& status);
Bytes encode(const Profile& profile);
// The size of the packet of a profile with `points` points.
constexpr std::size_t profilePacketSize(int points) {
  return kProfileHeaderSize + kPointSize * static_cast<std::size_t>(points);
}

Identity decodeIdentity(ByteView bytes);
DigitizerConfig decodeConfig(ByteView bytes);
ConfigReply decodeConfigReply(ByteView bytes);
DeviceStatus decodeStatus(ByteView bytes);
Profile decodeProfile(ByteView bytes);

}  // namespace stampscan::drivers::digitizer
