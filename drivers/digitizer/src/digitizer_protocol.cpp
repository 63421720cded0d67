#include "stampscan/drivers/digitizer/digitizer_protocol.hpp"

#include <bit>
#include <cmath>
#include <cstring>

namespace stampscan::drivers::digitizer {
namespace {

// Little-endian on the wire whatever the host; the project targets little-endian hosts, but the
// explicit byte shuffling keeps the format independent of that.
class Writer {
 public:
  explicit Writer(std::size_t reserve) { bytes_.reserve(reserve); }
  void u8(std::uint8_t v) { bytes_.push_back(v); }
  void u16(std::uint16_t v) { putLe(v, 2); }
  void u32(std::uint32_t v) { putLe(v, 4); }
  void u64(std::uint64_t v) { putLe(v, 8); }
  void f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }
  void str(const std::string& s, const char* field) {
    if (s.size() > kMaxStringLength) throw ProtocolError(field, "longer than 64 bytes");
    u8(static_cast<std::uint8_t>(s.size()));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
  }
  Bytes take() { return std::move(bytes_); }

 private:
  void putLe(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) bytes_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  Bytes bytes_;
};

class Reader {
 public:
  explicit Reader(ByteView bytes) : bytes_(bytes) {}
  std::uint8_t u8(const char* field) { return static_cast<std::uint8_t>(getLe(1, field)); }
  std::uint16_t u16(const char* field) { return static_cast<std::uint16_t>(getLe(2, field)); }
  std::uint32_t u32(const char* field) { return static_cast<std::uint32_t>(getLe(4, field)); }
  std::uint64_t u64(const char* field) { return getLe(8, field); }
  float f32(const char* field) { return std::bit_cast<float>(u32(field)); }
  std::string str(const char* field) {
    const std::size_t n = u8(field);
    if (n > kMaxStringLength) throw ProtocolError(field, "length " + std::to_string(n) + " > 64");
    need(n, field);
    std::string s(reinterpret_cast<const char*>(bytes_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  std::size_t remaining() const { return bytes_.size() - pos_; }
  void end(const char* what) const {
    if (remaining() != 0)
      throw ProtocolError(what, std::to_string(remaining()) + " unexpected trailing bytes");
  }

 private:
  void need(std::size_t n, const char* field) const {
    if (remaining() < n)
      throw ProtocolError(field, "truncated at byte " + std::to_string(pos_) + " of " +
                                     std::to_string(bytes_.size()));
  }
  std::uint64_t getLe(int n, const char* field) {
    need(static_cast<std::size_t>(n), field);
    std::uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= std::uint64_t{bytes_[pos_ + static_cast<std::size_t>(i)]} << (8 * i);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }
  ByteView bytes_;
  std::size_t pos_ = 0;
};

void writeConfig(Writer& w, const DigitizerConfig& c) {
  validate(c);
  w.u16(static_cast<std::uint16_t>(c.points_per_profile));
  w.u16(0);  // reserved, keeps the u32 fields aligned
  w.u32(static_cast<std::uint32_t>(std::lround(c.profile_rate_hz * 1000)));
  w.u32(c.exposure_us);
}

DigitizerConfig readConfig(Reader& r) {
  DigitizerConfig c;
  c.points_per_profile = r.u16("points_per_profile");
  if (r.u16("reserved") != 0) throw ProtocolError("reserved", "must be 0");
  c.profile_rate_hz = r.u32("profile_rate_mhz") / 1000.0;
  c.exposure_us = r.u32("exposure_us");
  validate(c);
  return c;
}

}  // namespace

const char* toString(Request request) {
  switch (request) {
    case Request::GetIdentity: return "GetIdentity";
    case Request::SetConfig: return "SetConfig";
    case Request::GetConfig: return "GetConfig";
    case Request::Start: return "Start";
    case Request::Stop: return "Stop";
    case Request::GetStatus: return "GetStatus";
  }
  return "unknown";
}

void validate(const DigitizerConfig& c) {
  if (c.points_per_profile < kMinPoints || c.points_per_profile > kMaxPoints)
    throw ProtocolError("points_per_profile",
                        std::to_string(c.points_per_profile) + " outside " + std::to_string(kMinPoints) + ".." +
                            std::to_string(kMaxPoints));
  if (!(c.profile_rate_hz >= kMinProfileRateHz && c.profile_rate_hz <= kMaxProfileRateHz))
    throw ProtocolError("profile_rate_mhz", "rate " + std::to_string(c.profile_rate_hz) + " Hz outside " +
                                                std::to_string(static_cast<int>(kMinProfileRateHz)) + ".." +
                                                std::to_string(static_cast<int>(kMaxProfileRateHz)) + " Hz");
  if (c.exposure_us < 1 || c.exposure_us > 1e6 / c.profile_rate_hz)
    throw ProtocolError("exposure_us", std::to_string(c.exposure_us) +
                                           " us: must be 1 .. one profile period");
}

Bytes encode(const Identity& id) {
  Writer w(kIdentityMaxSize);
  w.u16(id.protocol_version);
  w.str(id.model, "model");
  w.str(id.serial, "serial");
  w.str(id.firmware, "firmware");
  return w.take();
}

Bytes encode(const DigitizerConfig& config) {
  Writer w(kConfigSize);
  writeConfig(w, config);
  return w.take();
}

Bytes encode(const ConfigReply& reply) {
  Writer w(kConfigReplySize);
  writeConfig(w, reply.config);
  w.f32(reply.angle_min);
  w.f32(reply.angle_increment);
  return w.take();
}

Bytes encode(const DeviceStatus& s) {
  Writer w(kStatusSize);
  w.u32(s.status_word);
  w.u32(s.next_sequence);
  w.u64(s.device_time_ns);
  return w.take();
}

Bytes encode(const Profile& p) {
  if (p.range.size() != p.intensity.size())
    throw ProtocolError("point_count", "range and intensity differ in length");
  if (p.range.size() > static_cast<std::size_t>(kMaxPoints))
    throw ProtocolError("point_count", "more than 4096 points");
  Writer w(profilePacketSize(static_cast<int>(p.range.size())));
  w.u32(kProfileMagic);
  w.u32(p.sequence);
  w.u64(p.device_time_ns);
  w.u32(p.status);
  w.u16(static_cast<std::uint16_t>(p.range.size()));
  w.u16(0);
  for (std::size_t i = 0; i < p.range.size(); ++i) {
    w.f32(p.range[i]);
    w.u16(p.intensity[i]);
  }
  return w.take();
}

Identity decodeIdentity(ByteView bytes) {
  Reader r(bytes);
  Identity id;
  id.protocol_version = r.u16("protocol_version");
  if (id.protocol_version != kProtocolVersion)
    throw ProtocolError("protocol_version", "version " + std::to_string(id.protocol_version) +
                                                " (this host speaks 1)");
  id.model = r.str("model");
  id.serial = r.str("serial");
  id.firmware = r.str("firmware");
  r.end("identity");
  return id;
}

DigitizerConfig decodeConfig(ByteView bytes) {
  Reader r(bytes);
  DigitizerConfig c = readConfig(r);
  r.end("config");
  return c;
}

ConfigReply decodeConfigReply(ByteView bytes) {
  Reader r(bytes);
  ConfigReply reply;
  reply.config = readConfig(r);
  reply.angle_min = r.f32("angle_min");
  reply.angle_increment = r.f32("angle_increment");
  if (!std::isfinite(reply.angle_min) || !std::isfinite(reply.angle_increment))
    throw ProtocolError("angle_min", "fan angles not finite");
  r.end("config reply");
  return reply;
}

DeviceStatus decodeStatus(ByteView bytes) {
  Reader r(bytes);
  DeviceStatus s;
  s.status_word = r.u32("status_word");
  s.next_sequence = r.u32("next_sequence");
  s.device_time_ns = r.u64("device_time_ns");
  r.end("status");
  return s;
}

Profile decodeProfile(ByteView bytes) {
  Reader r(bytes);
  const std::uint32_t magic = r.u32("magic");
  if (magic != kProfileMagic) throw ProtocolError("magic", "not a profile packet");
  Profile p;
  p.sequence = r.u32("sequence");
  p.device_time_ns = r.u64("device_time_ns");
  p.status = r.u32("status");
  const std::size_t n = r.u16("point_count");
  if (r.u16("reserved") != 0) throw ProtocolError("reserved", "must be 0");
  if (n > static_cast<std::size_t>(kMaxPoints))
    throw ProtocolError("point_count", std::to_string(n) + " > 4096");
  // Checked before allocating, so that a corrupt count cannot make us reserve memory for nothing.
  if (r.remaining() != n * kPointSize)
    throw ProtocolError("point_count", std::to_string(n) + " points need " +
                                           std::to_string(n * kPointSize) + " bytes, packet has " +
                                           std::to_string(r.remaining()));
  p.range.resize(n);
  p.intensity.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const float range = r.f32("range");
    if (!std::isfinite(range) || range < 0)
      throw ProtocolError("range", "point " + std::to_string(i) + " not a finite range >= 0");
    p.range[i] = range;
    p.intensity[i] = r.u16("intensity");
  }
  return p;
}

}  // namespace stampscan::drivers::digitizer
