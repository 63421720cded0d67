// A thin owner of one libmodbus TCP client context: connect, close, and the requests the PLC driver
// uses, each turning libmodbus's errno into a ModbusFailure. Not thread-safe (libmodbus contexts are
// not): each instance has one user at a time. Private to src/: libmodbus stays out of public headers.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

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

// Shuts a socket down when a deadline passes, from its own thread. libmodbus bounds the wait for
// the first byte of a reply and then for each further byte, never the reply as a whole: a device that
// sends one byte every 0.4 s holds a request for minutes. A socket that is shut down makes
// libmodbus's select() and recv() return at once, so the request ends at the deadline.
class SocketDeadline {
 public:
  using Clock = std::chrono::steady_clock;
  SocketDeadline();
  ~SocketDeadline();
  SocketDeadline(const SocketDeadline&) = delete;
  SocketDeadline& operator=(const SocketDeadline&) = delete;

  void arm(int fd, Clock::time_point deadline);
  // Call before the socket is closed: the watcher never touches a descriptor after this returns.
  // True when the deadline passed and the socket was shut down.
  bool disarm();

 private:
  void watch();

  std::mutex mutex_;
  std::condition_variable changed_;
  int fd_ = -1;  // armed while >= 0
  Clock::time_point deadline_;
  bool expired_ = false;
  bool stop_ = false;
  std::thread watcher_;
};

class ModbusClient {
 public:
  // host: a name or address (IPv4 or IPv6); the context is created here, the connection later.
  // `timeout` bounds each request from sending to the end of its reply; `connect_timeout` bounds
  // establishing the TCP connection.
  ModbusClient(const std::string& host, int port, int unit_id, std::chrono::milliseconds timeout,
               std::chrono::milliseconds connect_timeout);
  ~ModbusClient();
  ModbusClient(const ModbusClient&) = delete;
  ModbusClient& operator=(const ModbusClient&) = delete;

  // Connects when not connected; true when it connected now. Throws ModbusFailure: ETIMEDOUT when
  // nothing answered within the connect timeout, the connect error otherwise.
  bool ensureConnected();
  void close() noexcept;
  bool connected() const { return connected_; }
  // The whole-request bound. Values below 1 ms are raised to 1 ms.
  void setResponseTimeout(std::chrono::microseconds timeout);
  void setConnectTimeout(std::chrono::milliseconds timeout);

  void readInputBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest);
  void readBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest);
  void readInputRegisters(std::uint16_t address, std::uint16_t count, std::uint16_t* dest);
  void readRegisters(std::uint16_t address, std::uint16_t count, std::uint16_t* dest);
  void writeBit(std::uint16_t address, bool on);
  void writeBits(std::uint16_t address, std::uint16_t count, const std::uint8_t* values);
  void writeRegister(std::uint16_t address, std::uint16_t value);
  void writeRegisters(std::uint16_t address, std::uint16_t count, const std::uint16_t* values);

 private:
  // Runs one libmodbus request under the whole-request deadline. Throws ModbusFailure naming the
  // request when it fails (libmodbus's -1) or the deadline passed.
  template <class Call>
  void run(const char* request, std::uint16_t address, Call call);
  void setLibmodbusTimeout(std::chrono::microseconds timeout);

  std::string where_;  // host:port, for messages
  modbus_t* context_ = nullptr;
  bool connected_ = false;
  std::chrono::microseconds timeout_;
  std::chrono::milliseconds connect_timeout_;
  SocketDeadline deadline_;
};

}  // namespace stampscan::drivers::plc::detail
