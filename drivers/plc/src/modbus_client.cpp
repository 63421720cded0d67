#include "modbus_client.hpp"

#include <sys/socket.h>

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

SocketDeadline::SocketDeadline() : watcher_([this] { watch(); }) {}

SocketDeadline::~SocketDeadline() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  watcher_.join();
}

void SocketDeadline::arm(int fd, Clock::time_point deadline) {
  {
    std::lock_guard lock(mutex_);
    fd_ = fd;
    deadline_ = deadline;
    expired_ = false;
  }
  changed_.notify_all();
}

bool SocketDeadline::disarm() {
  std::lock_guard lock(mutex_);
  fd_ = -1;
  return expired_;
}

void SocketDeadline::watch() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    if (fd_ < 0) {
      changed_.wait(lock);
    } else if (Clock::now() >= deadline_) {
      // Under the lock, and only while armed: disarm() comes before the owner closes the socket, so
      // this never shuts down a descriptor that has been closed and reused meanwhile.
      ::shutdown(fd_, SHUT_RDWR);
      expired_ = true;
      fd_ = -1;
    } else {
      changed_.wait_until(lock, deadline_);
    }
  }
}

namespace {
std::string millisecondsText(std::chrono::microseconds d) {
  return std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(d).count()) + " ms";
}
}  // namespace

ModbusClient::ModbusClient(const std::string& host, int port, int unit_id,
                           std::chrono::milliseconds timeout,
                           std::chrono::milliseconds connect_timeout)
    : where_(host + ":" + std::to_string(port)), timeout_(timeout), connect_timeout_(connect_timeout) {
  // The _pi variant resolves names and IPv6 addresses; plain modbus_new_tcp takes dotted IPv4 only.
  const std::string service = std::to_string(port);
  context_ = modbus_new_tcp_pi(host.c_str(), service.c_str());
  if (context_ == nullptr)
    throw ModbusFailure("cannot create a Modbus context for " + where_, errno);
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
  // libmodbus bounds its non-blocking connect with the response timeout.
  setLibmodbusTimeout(connect_timeout_);
  const int rc = modbus_connect(context_);
  const int error = errno;
  setLibmodbusTimeout(timeout_);
  if (rc == -1) {
    modbus_close(context_);
    // A connect that did not finish in time leaves errno at EINPROGRESS ("Operation now in
    // progress"), which tells an operator nothing: say what happened instead.
    if (error == EINPROGRESS || error == ETIMEDOUT || error == EALREADY)
      throw ModbusFailure("PLC at " + where_ + " does not answer (no connection within " +
                              millisecondsText(connect_timeout_) + ")",
                          ETIMEDOUT);
    if (error == ECONNREFUSED)
      throw ModbusFailure("PLC at " + where_ + " refuses the connection (nothing listens on that port)",
                          error);
    throw ModbusFailure("cannot connect to the PLC at " + where_ + ": " + modbus_strerror(error), error);
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
  timeout_ = std::max<std::chrono::microseconds>(timeout, std::chrono::milliseconds(1));
  setLibmodbusTimeout(timeout_);
}

void ModbusClient::setConnectTimeout(std::chrono::milliseconds timeout) {
  connect_timeout_ = std::max(timeout, std::chrono::milliseconds(1));
}

void ModbusClient::setLibmodbusTimeout(std::chrono::microseconds timeout) {
  const auto micros = std::max<std::int64_t>(timeout.count(), 1000);
  modbus_set_response_timeout(context_, static_cast<std::uint32_t>(micros / 1000000),
                              static_cast<std::uint32_t>(micros % 1000000));
}

template <class Call>
void ModbusClient::run(const char* request, std::uint16_t address, Call call) {
  deadline_.arm(modbus_get_socket(context_), SocketDeadline::Clock::now() + timeout_);
  const int rc = call();
  const int error = errno;
  const bool expired = deadline_.disarm();
  const std::string what = std::string(request) + " at address " + std::to_string(address);
  if (expired || (rc == -1 && error == ETIMEDOUT)) {
    // The socket may be shut down: the next request starts on a fresh connection.
    close();
    if (rc != -1) return;  // the reply was complete just as the deadline passed
    throw ModbusFailure(what + ": no complete reply within " + millisecondsText(timeout_), ETIMEDOUT);
  }
  if (rc == -1) throw ModbusFailure(what + ": " + modbus_strerror(error), error);
}

void ModbusClient::readInputBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest) {
  run("read discrete inputs", address, [&] { return modbus_read_input_bits(context_, address, count, dest); });
}

void ModbusClient::readBits(std::uint16_t address, std::uint16_t count, std::uint8_t* dest) {
  run("read coils", address, [&] { return modbus_read_bits(context_, address, count, dest); });
}

void ModbusClient::readInputRegisters(std::uint16_t address, std::uint16_t count,
                                      std::uint16_t* dest) {
  run("read input registers", address, [&] { return modbus_read_input_registers(context_, address, count, dest); });
}

void ModbusClient::readRegisters(std::uint16_t address, std::uint16_t count, std::uint16_t* dest) {
  run("read holding registers", address, [&] { return modbus_read_registers(context_, address, count, dest); });
}

void ModbusClient::writeBit(std::uint16_t address, bool on) {
  run("write coil", address, [&] { return modbus_write_bit(context_, address, on ? 1 : 0); });
}

void ModbusClient::writeBits(std::uint16_t address, std::uint16_t count,
                             const std::uint8_t* values) {
  run("write coils", address, [&] { return modbus_write_bits(context_, address, count, values); });
}

void ModbusClient::writeRegister(std::uint16_t address, std::uint16_t value) {
  run("write holding register", address, [&] { return modbus_write_register(context_, address, value); });
}

void ModbusClient::writeRegisters(std::uint16_t address, std::uint16_t count, const std::uint16_t* values) {
  run("write holding registers", address, [&] { return modbus_write_registers(context_, address, count, values); });
}

}  // namespace stampscan::drivers::plc::detail
