// The virtual cell PLC: a libmodbus TCP server serving the signals of
// drivers/plc/plc_register_map.hpp at the addresses of its options' register map, with the PLC's interlock logic running in the server. The station
// reaches it through the same ModbusPlc driver as the real PLC; tests and the simulator drive its
// inputs (door, e-stop, light curtain, clamp, air) and inject faults (silence, slow replies, dropped
// connections) through this class.
//
// Interlock (as documented in drivers/plc/REGISTER_MAP.md): while the door is open, the e-stop chain
// is broken, the light curtain is interrupted, or the station heartbeat has not changed for longer
// than watchdog_timeout_ms, the PLC forces laser_shutter_open_request and motion_enable to 0 (so the
// shutter closes and motion stops) and reports interlock_state 1 with the causes in fault_word. The
// coils stay 0 once the cause is gone, until the station writes them again: no automatic restart.
//
// Threads: one accepting connections, one per connection (each with its own libmodbus context, since
// contexts are not thread-safe), one for the logic cycle. All of them share the register image under
// one mutex. Every public method is thread-safe. The destructor stops and joins them all.
//
// Nothing on the network can stop it or hold it: connections are capped (max_connections), idle ones
// closed (idle_timeout), a request must arrive whole (request_timeout) and its reply leave
// (send_timeout); out of file descriptors, the acceptor backs off instead of spinning.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "stampscan/drivers/plc/plc_register_map.hpp"

namespace stampscan::sim {

struct VirtualPlcOptions {
  std::string address = "127.0.0.1";  // IPv4 address to listen on
  int port = drivers::plc::kDefaultTcpPort;  // 0: an ephemeral port, readable with port() after start()
  std::uint16_t firmware_major = 1;
  std::uint16_t firmware_minor = 0;
  std::uint16_t watchdog_timeout_ms = drivers::plc::kDefaultWatchdogTimeoutMs;  // initial value
  // The logic cycle: heartbeat watchdog, plc_heartbeat counter. Input changes made through this
  // class and requests from clients are acted on at once, not at the next cycle.
  std::chrono::milliseconds cycle{10};

  // The unit id served (the cell config's plc.unit_id); 0xFF, "the device itself" on TCP, is
  // served too. Other units get exception 0x0B, other protocol ids no answer (src/modbus_frame.hpp).
  std::uint8_t unit_id = 1;
  // Connections. The station's watchdog polls every 100 ms; its request connection may rest between
  // calls and reconnects on its own when it finds itself closed. A minute frees a connection thread
  // whose client vanished without closing.
  std::chrono::milliseconds idle_timeout{std::chrono::seconds(60)};
  // A request that has begun must be complete within this, or the connection is closed (a client
  // that dribbles bytes cannot hold a connection thread).
  std::chrono::milliseconds request_timeout{std::chrono::seconds(2)};
  // A reply must find room in the socket within this, or the connection is closed (a client that
  // sends requests but never reads the replies).
  std::chrono::milliseconds send_timeout{std::chrono::seconds(2)};
  // Open connections at most; one more is accepted and closed at once, so that its client fails
  // fast instead of waiting in the listen queue. The station uses two.
  std::size_t max_connections = 16;
  // Where each signal is served (the cell file's [plc.registers]; default: the standard map). The
  // image covers each kind's span of the map; addresses outside it get exception 0x02. The
  // constructor refuses a map with a clash or a span wider than kMaxAddressSpan
  // (std::invalid_argument naming the signals).
  drivers::plc::RegisterMap registers;
};

class VirtualPlc {
 public:
  using DiscreteInput = drivers::plc::DiscreteInput;
  using Coil = drivers::plc::Coil;
  using HoldingRegister = drivers::plc::HoldingRegister;
  using InputRegister = drivers::plc::InputRegister;

  // The cell starts healthy: door closed, e-stop chain OK, curtain clear, air OK, part unclamped,
  // shutter closed, every coil 0. Nothing listens until start().
  explicit VirtualPlc(VirtualPlcOptions options = {});
  ~VirtualPlc();
  VirtualPlc(const VirtualPlc&) = delete;
  VirtualPlc& operator=(const VirtualPlc&) = delete;

  // Listens and starts serving; throws std::runtime_error naming the address when it cannot.
  void start();
  // Closes every connection and joins every thread; the register image is kept. Idempotent.
  void stop() noexcept;
  bool running() const;
  int port() const;  // the bound port (the ephemeral one when options.port was 0); 0 before start()
  const VirtualPlcOptions& options() const { return options_; }

  // Inputs, as the cell's sensors would set them; the PLC logic acts on the change at once.
  // laser_shutter_closed is the shutter's own feedback and always follows its request: setting it
  // here is overwritten.
  void setInput(DiscreteInput input, bool on);
  void openDoor() { setInput(DiscreteInput::DoorClosed, false); }
  void closeDoor() { setInput(DiscreteInput::DoorClosed, true); }
  void breakEStopChain() { setInput(DiscreteInput::EStopChainOk, false); }
  void restoreEStopChain() { setInput(DiscreteInput::EStopChainOk, true); }
  void interruptLightCurtain() { setInput(DiscreteInput::LightCurtainClear, false); }
  void clearLightCurtain() { setInput(DiscreteInput::LightCurtainClear, true); }
  // The clamp follows clamp_request on its own; this overrides it (a part that slipped, a stuck clamp).
  void setPartClamped(bool clamped) { setInput(DiscreteInput::PartClamped, clamped); }
  void setAirPressureOk(bool ok) { setInput(DiscreteInput::AirPressureOk, ok); }

  // The register image, as a client would read it.
  bool input(DiscreteInput input) const;
  bool coil(Coil coil) const;
  std::uint16_t holdingRegister(HoldingRegister reg) const;
  std::uint16_t inputRegister(InputRegister reg) const;
  bool interlockTripped() const;
  std::uint16_t faultWord() const;
  // How many times the station heartbeat register changed value.
  std::uint64_t stationHeartbeatChanges() const;

  // The line's side of the handshake (REGISTER_MAP.md, "Started by the line"), as the line's PLC
  // plays it: requestStart writes line_program_number and line_part_id, then line_start_request 1;
  // dropStartRequest writes it 0. Throws std::invalid_argument for a part id the registers cannot
  // hold (drivers::plc::encodePartId). A client can do the same over Modbus.
  void requestStart(std::uint16_t program_number, std::string_view part_id);
  void dropStartRequest();
  // The cell's answer (cell_* registers), as the line reads it.
  drivers::plc::CellAnswer cellAnswer() const;

  // Fault injection.
  // Silent: requests are read and dropped, never answered (a PLC whose program hangs).
  void setSilent(bool silent);
  // Every reply waits this long first (0: none); beyond the client's timeout, the client times out.
  void setReplyDelay(std::chrono::milliseconds delay);
  // Closes every open client connection now; clients may connect again.
  void dropConnections();

  std::size_t connectionCount() const;
  std::uint64_t requestsAnswered() const;  // exception responses included
  std::uint64_t connectionsRefused() const;  // over max_connections

 private:
  struct Impl;
  VirtualPlcOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::sim
