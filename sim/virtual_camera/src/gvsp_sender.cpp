#include "gvsp_sender.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/uio.h>

#include <algorithm>
#include <array>

#include "gvcp_protocol.hpp"

namespace stampscan::sim::gvsp {

namespace {

using gvcp::writeBe16;
using gvcp::writeBe32;

// Aravis' own lower bound for GevSCPSPacketSize; below it a frame would take tens of thousands
// of packets. The upper bound is the largest IPv4 UDP datagram.
constexpr std::uint32_t kMinPacketSize = 220;
constexpr std::uint32_t kMaxPacketSize = 65535;

void writeHeader(std::span<std::uint8_t> out, std::uint16_t block_id, std::uint8_t format, std::uint32_t packet_id) {
  writeBe16(out, 0, 0);  // status: success
  writeBe16(out, 2, block_id);
  // EI (extended id) flag clear, then the packet format and the 24-bit packet id.
  writeBe32(out, 4, (std::uint32_t{format} << 24) | (packet_id & 0x00FFFFFF));
}

}  // namespace

bool Sender::drop(double ratio) {
  if (ratio <= 0.0) return false;
  // The top 53 bits of the generator as a double in [0, 1): the same sequence everywhere.
  const double u = static_cast<double>(random_() >> 11) * 0x1.0p-53;
  return u < ratio;
}

void Sender::send(const Destination& to, std::span<const std::uint8_t> header, std::span<const std::uint8_t> body) {
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(to.address);
  address.sin_port = htons(to.port);
  std::array<iovec, 2> parts{{{const_cast<std::uint8_t*>(header.data()), header.size()},
                              {const_cast<std::uint8_t*>(body.data()), body.size()}}};
  msghdr message{};
  message.msg_name = &address;
  message.msg_namelen = sizeof address;
  message.msg_iov = parts.data();
  message.msg_iovlen = body.empty() ? 1 : 2;
  // A lost datagram is what GVSP is built to survive; the receiver counts it.
  (void)sendmsg(fd_, &message, MSG_NOSIGNAL);
}

std::uint64_t Sender::sendBlock(const BlockInfo& info, std::span<const std::uint8_t> image, const Destination& to,
                                std::uint32_t packet_size, double lost_packet_ratio) {
  const std::uint32_t data_per_packet =
      std::clamp(packet_size, kMinPacketSize, kMaxPacketSize) - gvcp::kGvspPacketOverhead;
  std::uint64_t dropped = 0;
  std::uint32_t packet_id = 0;

  // Leader (image payload type): reserved(16) payload_type(16) timestamp(64) pixel_format(32)
  // size_x size_y offset_x offset_y (32 each) padding_x padding_y (16 each).
  std::array<std::uint8_t, gvcp::kGvspHeaderSize + 36> leader{};
  writeHeader(leader, info.block_id, gvcp::kGvspLeader, packet_id++);
  std::span<std::uint8_t> l = std::span(leader).subspan(gvcp::kGvspHeaderSize);
  writeBe16(l, 2, gvcp::kGvspPayloadTypeImage);
  writeBe32(l, 4, static_cast<std::uint32_t>(info.timestamp >> 32));
  writeBe32(l, 8, static_cast<std::uint32_t>(info.timestamp));
  writeBe32(l, 12, info.pixel_format);
  writeBe32(l, 16, info.width);
  writeBe32(l, 20, info.height);
  writeBe32(l, 24, info.offset_x);
  writeBe32(l, 28, info.offset_y);
  if (drop(lost_packet_ratio)) ++dropped; else send(to, leader, {});

  std::array<std::uint8_t, gvcp::kGvspHeaderSize> header{};
  for (std::size_t offset = 0; offset < image.size(); offset += data_per_packet) {
    writeHeader(header, info.block_id, gvcp::kGvspPayload, packet_id++);
    const std::span<const std::uint8_t> chunk = image.subspan(offset, std::min<std::size_t>(data_per_packet, image.size() - offset));
    if (drop(lost_packet_ratio)) ++dropped; else send(to, header, chunk);
  }

  // Trailer (image payload type): reserved(16) payload_type(16) size_y(32).
  std::array<std::uint8_t, gvcp::kGvspHeaderSize + 8> trailer{};
  writeHeader(trailer, info.block_id, gvcp::kGvspTrailer, packet_id);
  std::span<std::uint8_t> t = std::span(trailer).subspan(gvcp::kGvspHeaderSize);
  writeBe16(t, 2, gvcp::kGvspPayloadTypeImage);
  writeBe32(t, 4, info.height);
  if (drop(lost_packet_ratio)) ++dropped; else send(to, trailer, {});
  return dropped;
}

}  // namespace stampscan::sim::gvsp
