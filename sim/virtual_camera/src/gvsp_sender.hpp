// GVSP for the virtual cameras: one image block as a leader, payload packets and a trailer (GigE
// Vision GVSP, standard 16-bit block ids), sent on the camera's stream socket. Packets are dropped
// at random with the configured ratio, to exercise the receiver's loss handling.
#pragma once

#include <cstdint>
#include <random>
#include <span>

namespace stampscan::sim::gvsp {

struct BlockInfo {
  std::uint16_t block_id = 1;  // 1..65535 (0 is not a valid GVSP 1.x block id)
  std::uint64_t timestamp = 0; // device ticks (ns: the tick frequency register says 1 GHz)
  std::uint32_t pixel_format = 0, width = 0, height = 0, offset_x = 0, offset_y = 0;
};

struct Destination {
  std::uint32_t address = 0;  // IPv4, host byte order
  std::uint16_t port = 0;
};

class Sender {
 public:
  explicit Sender(int socket_fd) : fd_(socket_fd) {}

  // Sends `image` as one block. `packet_size` is GevSCPSPacketSize (IP + UDP + GVSP headers
  // included), clamped to what a UDP datagram can carry. Returns the number of packets dropped.
  std::uint64_t sendBlock(const BlockInfo& info, std::span<const std::uint8_t> image, const Destination& to,
                          std::uint32_t packet_size, double lost_packet_ratio);

 private:
  bool drop(double ratio);
  void send(const Destination& to, std::span<const std::uint8_t> header, std::span<const std::uint8_t> body);

  int fd_;
  std::mt19937_64 random_{0x5ca1ab1e};
};

// The next GVSP 1.x block id: 16 bits, 0 skipped.
inline std::uint16_t nextBlockId(std::uint16_t id) { return id == 0xFFFF ? 1 : static_cast<std::uint16_t>(id + 1); }

}  // namespace stampscan::sim::gvsp
