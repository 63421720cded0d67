// A thin owner of one libmodbus TCP client context: connect, close, and the requests the PLC driver
// uses, each turning libmodbus's errno into a ModbusFailure. Not thread-safe (libmodbus contexts are
// not): each instance has one user at a time. Private to src/: libmodbus stays out of public headers.
#pragma once

#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <modbus.h>

namespace stampscan::drivers::plc::detail {

class ModbusFailure : public std::runtime_error {
 public:
  ModbusFailure(const std::string& text, int error_number);
  int errorNumber() const { return error_number_; }
  // The Device fault code: "timeout", "disconnected" or "protocol".
  const char* code() const;
  bool isTimeout() const;
  // The TCP connection is gone (reset, refused, closed by the peer); a reconnect may help.
  bool isConnectionLost() const;

 private:
  int error_number_;
};

class ModbusClient {
 public:
  // host: a name or address (IPv4 or IPv6); the context is created here, the connection later.
  ModbusClient(const std::string& host, int port, int unit_id, std::chrono::milliseconds timeout);
  ~ModbusClient();
  ModbusClient(const ModbusClient&) = delete;
  ModbusClient& operator=(const ModbusClient&) = delete;

  // Connects when not connected; true when it connected now. Throws ModbusFailure.
  bool ensureConnected();
  void close() noexcept;
  bool connected() const { return connected_; }
  // Also bounds connect(). Values below 1 ms are raised to 1 ms.
  void setResponseTimeout(std::chrono::microseconds timeout);

  void readInputBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest);
  void readBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest);
  void readInputRegisters(std::uint16_t address, std::uint16_t count, std::uint16_t* dest);
  void readRegisters(std::uint16_t address, std::uint16_t count, std::uint16_t* dest);
  void writeBit(std::uint16_t address, bool on);
  void writeBits(std::uint16_t address, std::uint16_t count, const std::uint8_t* values);
  void writeRegister(std::uint16_t address, std::uint16_t value);

 private:
  // Throws ModbusFailure naming the request when rc is -1 (libmodbus's failure return).
  void check(int rc, const char* request, std::uint16_t address) const;

  modbus_t* context_ = nullptr;
  bool connected_ = false;
};

}  // namespace stampscan::drivers::plc::detail
