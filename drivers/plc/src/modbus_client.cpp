#include "modbus_client.hpp"

#include <algorithm>
#include <cerrno>

namespace stampscan::drivers::plc::detail {

ModbusFailure::ModbusFailure(const std::string& text, int error_number)
    : std::runtime_error(text), error_number_(error_number) {}

bool ModbusFailure::isTimeout() const { return error_number_ == ETIMEDOUT; }

bool ModbusFailure::isConnectionLost() const {
  switch (error_number_) {
    case ECONNRESET:    // libmodbus's report of a peer that closed the connection (recv() == 0)
    case ECONNREFUSED:
    case ECONNABORTED:
    case EPIPE:
    case ENOTCONN:
    case EBADF:
    case EHOSTUNREACH:
    case ENETUNREACH:
    case EINPROGRESS:   // a non-blocking connect that did not complete
      return true;
    default:
      return false;
  }
}

const char* ModbusFailure::code() const {
  if (isTimeout()) return "timeout";
  // Errors from MODBUS_ENOBASE up are Modbus exception replies and malformed frames.
  if (error_number_ >= MODBUS_ENOBASE) return "protocol";
  return "disconnected";
}

ModbusClient::ModbusClient(const std::string& host, int port, int unit_id,
                           std::chrono::milliseconds timeout) {
  // The _pi variant resolves names and IPv6 addresses; plain modbus_new_tcp takes dotted IPv4 only.
  const std::string service = std::to_string(port);
  context_ = modbus_new_tcp_pi(host.c_str(), service.c_str());
  if (context_ == nullptr)
    throw ModbusFailure("cannot create a Modbus context for " + host + ":" + service, errno);
  if (modbus_set_slave(context_, unit_id) == -1) {
    const int error = errno;
    modbus_free(context_);
    throw ModbusFailure("invalid unit id " + std::to_string(unit_id), error);
  }
  // No automatic recovery: the driver decides (close, reconnect, report) and counts what happened.
  modbus_set_error_recovery(context_, MODBUS_ERROR_RECOVERY_NONE);
  setResponseTimeout(timeout);
}

ModbusClient::~ModbusClient() {
  close();
  modbus_free(context_);
}

bool ModbusClient::ensureConnected() {
  if (connected_) return false;
  if (modbus_connect(context_) == -1) {
    const int error = errno;
    modbus_close(context_);
    throw ModbusFailure(std::string("connect: ") + modbus_strerror(error), error);
  }
  connected_ = true;
  return true;
}

void ModbusClient::close() noexcept {
  if (!connected_) return;
  modbus_close(context_);
  connected_ = false;
}

void ModbusClient::setResponseTimeout(std::chrono::microseconds timeout) {
  const auto micros = std::max<std::int64_t>(timeout.count(), 1000);
  modbus_set_response_timeout(context_, static_cast<std::uint32_t>(micros / 1000000),
                              static_cast<std::uint32_t>(micros % 1000000));
}

void ModbusClient::check(int rc, const char* request, std::uint16_t address) const {
  if (rc != -1) return;
  const int error = errno;
  throw ModbusFailure(std::string(request) + " at address " + std::to_string(address) + ": " +
                          modbus_strerror(error),
                      error);
}

void ModbusClient::readInputBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest) {
  check(modbus_read_input_bits(context_, address, count, dest), "read discrete inputs", address);
}

void ModbusClient::readBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest) {
  check(modbus_read_bits(context_, address, count, dest), "read coils", address);
}

void ModbusClient::readInputRegisters(std::uint16_t address, std::uint16_t count,
                                      std::uint16_t* dest) {
  check(modbus_read_input_registers(context_, address, count, dest), "read input registers",
        address);
}

void ModbusClient::readRegisters(std::uint16_t address, std::uint16_t count, std::uint16_t* dest) {
  check(modbus_read_registers(context_, address, count, dest), "read holding registers", address);
}

void ModbusClient::writeBit(std::uint16_t address, bool on) {
  check(modbus_write_bit(context_, address, on ? 1 : 0), "write coil", address);
}

void ModbusClient::writeBits(std::uint16_t address, std::uint16_t count,
                             const std::uint8_t* values) {
  check(modbus_write_bits(context_, address, count, values), "write coils", address);
}

void ModbusClient::writeRegister(std::uint16_t address, std::uint16_t value) {
  check(modbus_write_register(context_, address, value), "write holding register", address);
}

}  // namespace stampscan::drivers::plc::detail
