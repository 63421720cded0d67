// The digitizer's wire format: every message round-trips; malformed input of every kind throws a
// ProtocolError naming the field; a seeded replay of random mutations never gets anything else.
#include "stampscan/drivers/digitizer/digitizer_protocol.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

namespace stampscan::drivers::digitizer {
namespace {

Profile sampleProfile(int points, std::uint32_t sequence = 7) {
  Profile p;
  p.sequence = sequence;
  p.device_time_ns = 123456789012345ull;
  p.status = kStatusOverexposed;
  for (int i = 0; i < points; ++i) {
    p.range.push_back(i % 5 == 0 ? 0.0f : 80.0f + 0.25f * static_cast<float>(i));
    p.intensity.push_back(static_cast<std::uint16_t>(i * 131));
  }
  return p;
}

std::string fieldOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const ProtocolError& e) {
    return e.field();
  }
  return "(no error)";
}

TEST(DigitizerProtocol, MessagesRoundTrip) {
  const Identity id{kProtocolVersion, "SSD-1024", "SN-42", "2.3.1"};
  EXPECT_EQ(decodeIdentity(encode(id)), id);
  const DigitizerConfig config{2048, 1250.5, 300};
  EXPECT_EQ(encode(config).size(), kConfigSize);
  EXPECT_EQ(decodeConfig(encode(config)), config);
  const ConfigReply reply{config, -0.21f, 0.0002f};
  EXPECT_EQ(encode(reply).size(), kConfigReplySize);
  EXPECT_EQ(decodeConfigReply(encode(reply)), reply);
  const DeviceStatus status{kStatusStreaming | kStatusMirrorFault, 99, 1ull << 40};
  EXPECT_EQ(encode(status).size(), kStatusSize);
  EXPECT_EQ(decodeStatus(encode(status)), status);
  for (int points : {0, 1, 16, 1024, kMaxPoints}) {
    const Profile p = sampleProfile(points);
    const Bytes bytes = encode(p);
    EXPECT_EQ(bytes.size(), profilePacketSize(points));
    EXPECT_EQ(decodeProfile(bytes), p);
  }
}

TEST(DigitizerProtocol, ProfileLayoutIsLittleEndianAsDocumented) {
  const Bytes b = encode(sampleProfile(2, 0x01020304));
  EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "SSLP");
  EXPECT_EQ(b[4], 0x04);
  EXPECT_EQ(b[7], 0x01);
  EXPECT_EQ(b[20], 2);  // point_count
  float range1 = 0;
  std::memcpy(&range1, &b[24 + 6], 4);
  EXPECT_EQ(range1, 80.25f);
}

TEST(DigitizerProtocol, MalformedProfilesNameTheField) {
  const Bytes good = encode(sampleProfile(32));
  for (std::size_t n = 0; n < kProfileHeaderSize; ++n) {
    const std::string field = fieldOf([&] { decodeProfile(ByteView(good.data(), n)); });
    EXPECT_NE(field, "(no error)") << n;
  }
  EXPECT_EQ(fieldOf([&] { decodeProfile(ByteView(good.data(), 2)); }), "magic");
  Bytes b = good;
  b[0] ^= 1;
  EXPECT_EQ(fieldOf([&] { decodeProfile(b); }), "magic");
  b = good;
  b[20] = 33;  // one point more than the packet holds
  EXPECT_EQ(fieldOf([&] { decodeProfile(b); }), "point_count");
  b = good;
  b[21] = 0xff;  // 65k points
  EXPECT_EQ(fieldOf([&] { decodeProfile(b); }), "point_count");
  EXPECT_EQ(fieldOf([&] { decodeProfile(ByteView(good.data(), good.size() - 1)); }), "point_count");
  b = good;
  b.push_back(0);
  EXPECT_EQ(fieldOf([&] { decodeProfile(b); }), "point_count");
  b = good;
  b[22] = 1;
  EXPECT_EQ(fieldOf([&] { decodeProfile(b); }), "reserved");
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -1.0f}) {
    b = good;
    std::memcpy(&b[24 + 6 * 3], &bad, 4);
    EXPECT_EQ(fieldOf([&] { decodeProfile(b); }), "range");
  }
  Profile uneven = sampleProfile(4);
  uneven.intensity.pop_back();
  EXPECT_EQ(fieldOf([&] { encode(uneven); }), "point_count");
}

TEST(DigitizerProtocol, MalformedControlPayloadsNameTheField) {
  const Bytes id = encode(Identity{kProtocolVersion, "model", "serial", "fw"});
  for (std::size_t n = 0; n < id.size(); ++n)
    EXPECT_NE(fieldOf([&] { decodeIdentity(ByteView(id.data(), n)); }), "(no error)") << n;
  Bytes b = id;
  b[0] = 9;
  EXPECT_EQ(fieldOf([&] { decodeIdentity(b); }), "protocol_version");
  b = id;
  b[2] = 200;  // model length beyond 64
  EXPECT_EQ(fieldOf([&] { decodeIdentity(b); }), "model");
  EXPECT_EQ(fieldOf([&] { encode(Identity{1, std::string(65, 'x'), "", ""}); }), "model");

  EXPECT_EQ(fieldOf([] { validate({8, 500, 100}); }), "points_per_profile");
  EXPECT_EQ(fieldOf([] { validate({1024, 0, 100}); }), "profile_rate_mhz");
  EXPECT_EQ(fieldOf([] { validate({1024, 30000, 10}); }), "profile_rate_mhz");
  EXPECT_EQ(fieldOf([] { validate({1024, 1000, 1001}); }), "exposure_us");
  EXPECT_EQ(fieldOf([] { validate({1024, 1000, 0}); }), "exposure_us");
  const Bytes config = encode(DigitizerConfig{});
  EXPECT_EQ(fieldOf([&] { decodeConfig(ByteView(config.data(), 11)); }), "exposure_us");
  b = config;
  b.push_back(0);
  EXPECT_EQ(fieldOf([&] { decodeConfig(b); }), "config");
  b = encode(ConfigReply{DigitizerConfig{}, std::numeric_limits<float>::quiet_NaN(), 0});
  EXPECT_EQ(fieldOf([&] { decodeConfigReply(b); }), "angle_min");
  EXPECT_EQ(fieldOf([] { decodeStatus(Bytes(15)); }), "device_time_ns");
}

// Seeded, so a failure replays: random mutations of valid messages either decode to something
// that re-encodes to the same bytes, or throw ProtocolError; never anything else, never a crash.
TEST(DigitizerProtocol, SeededMutationReplay) {
  std::mt19937_64 rng(20240611);
  const std::vector<Bytes> seeds = {encode(sampleProfile(64)), encode(sampleProfile(0)),
                                    encode(Identity{1, "SSD", "VD-1", "1.0"}),
                                    encode(ConfigReply{DigitizerConfig{}, -0.2f, 0.001f}),
                                    encode(DeviceStatus{1, 2, 3})};
  int accepted = 0, rejected = 0;
  for (int iteration = 0; iteration < 20000; ++iteration) {
    Bytes b = seeds[rng() % seeds.size()];
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      switch (rng() % 4) {
        case 0: if (!b.empty()) b[rng() % b.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8)); break;
        case 1: if (!b.empty()) b[rng() % b.size()] = static_cast<std::uint8_t>(rng()); break;
        case 2: b.resize(rng() % (b.size() + 1)); break;
        default: b.insert(b.begin() + static_cast<std::ptrdiff_t>(rng() % (b.size() + 1)), static_cast<std::uint8_t>(rng())); break;
      }
    }
    auto check = [&](auto decode) {
      try {
        const auto message = decode(ByteView(b));
        EXPECT_EQ(encode(message), b) << "iteration " << iteration;
        ++accepted;
      } catch (const ProtocolError&) {
        ++rejected;
      }
    };
    check(decodeProfile);
    check(decodeIdentity);
    check(decodeConfigReply);
    check(decodeStatus);
  }
  EXPECT_GT(rejected, 0);
  EXPECT_GT(accepted, 0);
}

}  // namespace
}  // namespace stampscan::drivers::digitizer
