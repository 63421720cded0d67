// The virtual PLC's request framing and verdicts (sim/virtual_plc/src/modbus_frame.hpp), byte by
// byte: what reaches libmodbus, what is refused with which exception, what is dropped.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "modbus_frame.hpp"

namespace stampscan::sim::detail {
namespace {

using Bytes = std::vector<std::uint8_t>;

TEST(ModbusFrame, CutsAStreamAtTheMbapLengths) {
  const Bytes read{0, 1, 0, 0, 0, 6, 1, 0x04, 0, 0, 0, 6};
  const Bytes write{0, 2, 0, 0, 0, 6, 1, 0x06, 0, 1, 0x12, 0x34};
  Bytes stream = read;
  stream.insert(stream.end(), write.begin(), write.begin() + 5);
  ModbusTcpFramer framer;
  framer.append(stream);
  EXPECT_EQ(framer.next(), read);
  EXPECT_EQ(framer.next(), std::nullopt);
  EXPECT_EQ(framer.pendingBytes(), 5U);
  framer.append(std::span(write).subspan(5));
  EXPECT_EQ(framer.next(), write);
  EXPECT_EQ(framer.pendingBytes(), 0U);
  EXPECT_FALSE(framer.broken());
}

TEST(ModbusFrame, ALengthNoAduCanHaveBreaksTheStream) {
  for (const unsigned length : {0U, 1U, 255U, 0xFFFFU}) {
    ModbusTcpFramer framer;
    framer.append(Bytes{0, 1, 0, 0, static_cast<std::uint8_t>(length >> 8), static_cast<std::uint8_t>(length), 1});
    EXPECT_EQ(framer.next(), std::nullopt);
    EXPECT_TRUE(framer.broken()) << length;
  }
}

TEST(ModbusFrame, VerdictsFollowUnitProtocolFunctionAndLength) {
  const auto verdict = [](const Bytes& adu) { return checkRequest(adu, 1); };
  EXPECT_EQ(verdict({0, 1, 0, 0, 0, 6, 1, 0x04, 0, 0, 0, 6}).action, RequestAction::Serve);
  EXPECT_EQ(verdict({0, 1, 0, 0, 0, 6, 0xFF, 0x04, 0, 0, 0, 6}).action, RequestAction::Serve);
  EXPECT_EQ(verdict({0, 1, 0, 0, 0, 9, 1, 0x10, 0, 1, 0, 1, 2, 0, 5}).action, RequestAction::Serve);
  EXPECT_EQ(verdict({0, 1, 0, 7, 0, 6, 1, 0x04, 0, 0, 0, 6}).action, RequestAction::Drop);  // protocol 7

  const RequestVerdict other_unit = verdict({0, 1, 0, 0, 0, 6, 2, 0x04, 0, 0, 0, 6});
  EXPECT_EQ(other_unit.action, RequestAction::Refuse);
  EXPECT_EQ(other_unit.exception_code, kGatewayTargetFailed);
  const RequestVerdict function = verdict({0, 1, 0, 0, 0, 2, 1, 0x2B});
  EXPECT_EQ(function.exception_code, kIllegalFunction);
  const RequestVerdict short_pdu = verdict({0, 1, 0, 0, 0, 4, 1, 0x04, 0, 0});
  EXPECT_EQ(short_pdu.exception_code, kIllegalDataValue);
  const RequestVerdict byte_count = verdict({0, 1, 0, 0, 0, 9, 1, 0x10, 0, 1, 0, 1, 9, 0, 5});
  EXPECT_EQ(byte_count.exception_code, kIllegalDataValue) << "byte count 9 for 2 bytes";

  EXPECT_EQ(exceptionResponse(Bytes{0x12, 0x34, 0, 0, 0, 6, 2, 0x04, 0, 0, 0, 6}, kGatewayTargetFailed),
            (Bytes{0x12, 0x34, 0, 0, 0, 3, 2, 0x84, 0x0B}));
}

}  // namespace
}  // namespace stampscan::sim::detail
