// The cell PLC over Modbus TCP (libmodbus). The same driver talks to the real PLC and to the virtual
// PLC of sim/virtual_plc; only the address differs. What each bit and register means is in
// plc_register_map.hpp (and REGISTER_MAP.md); where each one is, in the options' register map (the
// cell file's [plc.registers]).
//
// Thread safety: every public method may be called from any thread. libmodbus contexts are not
// thread-safe, so each context has exactly one user at a time:
//  - the API's context (one TCP connection) is shared by the public methods behind a mutex;
//  - the watchdog thread owns a second context (its own TCP connection) outright.
// Two connections rather than one shared context, so that the watchdog is never queued behind a slow
// API call (nor the reverse): its silence deadline then holds to within a few milliseconds.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "stampscan/drivers/device.hpp"
#include "stampscan/drivers/plc/plc_register_map.hpp"

namespace stampscan::drivers::plc {

namespace detail {
class ModbusClient;
}

struct ModbusPlcOptions {
  std::string host = "127.0.0.1";
  int port = kDefaultTcpPort;
  int unit_id = 1;
  // How long one Modbus request may take, from sending it to the last byte of its reply, before it
  // fails with fault "timeout". A whole-request bound: a device that dribbles its reply byte by byte
  // cannot stretch it (libmodbus alone bounds each byte, not the reply).
  std::chrono::milliseconds response_timeout{500};
  // How long establishing the TCP connection may take before it fails with fault "timeout" ("PLC
  // at ... does not answer").
  std::chrono::milliseconds connect_timeout{2000};
  // Run the watchdog thread after connect: heartbeat write + state read every poll_period, change
  // events, and "plc-silent" when the PLC has not answered for silence_limit.
  bool watchdog = true;
  std::chrono::milliseconds poll_period{100};
  std::chrono::milliseconds silence_limit{1000};
  // Written to the PLC's watchdog_timeout_ms at connect when set (the PLC keeps its own otherwise).
  std::optional<std::uint16_t> plc_watchdog_timeout_ms;
  // Where the PLC program puts each signal (default: the standard map of REGISTER_MAP.md). Every
  // signal is read and written at its address here; a map with a clash or a span wider than
  // kMaxAddressSpan is refused.
  RegisterMap registers;
};

// The whole input state: discrete inputs and input registers, read in two requests (each kind's span
// of the register map, gaps included).
struct PlcInputs {
  bool door_closed = false;
  bool e_stop_chain_ok = false;
  bool light_curtain_clear = false;
  bool part_clamped = false;
  bool laser_shutter_closed = false;
  bool air_pressure_ok = false;
  std::uint16_t plc_heartbeat = 0;
  std::uint16_t station_heartbeat_echo = 0;
  std::uint16_t firmware_major = 0;
  std::uint16_t firmware_minor = 0;
  std::uint16_t fault_word = 0;  // FaultBit bits
  InterlockState interlock = InterlockState::Tripped;

  bool has(FaultBit bit) const { return (fault_word & mask(bit)) != 0; }
  bool interlockTripped() const { return interlock != InterlockState::Clear; }
};

// The coils, as the PLC holds them (after its interlock has had its say).
struct PlcOutputs {
  bool stack_light_green = false;
  bool stack_light_amber = false;
  bool stack_light_red = false;
  bool laser_shutter_open_request = false;
  bool clamp_request = false;
  bool motion_enable = false;
  bool operator==(const PlcOutputs&) const = default;
};

enum class PlcEventKind {
  DoorOpened, DoorClosed,
  EStopBroken, EStopRestored,
  LightCurtainInterrupted, LightCurtainCleared,
  AirPressureLost, AirPressureRestored,
  InterlockTripped, InterlockCleared,  // from the PLC's interlock_state (covers its heartbeat watchdog)
  ConnectionLost, Reconnected,
  PlcSilent, PlcAnswering,
};
const char* toString(PlcEventKind kind);

struct PlcEvent {
  std::chrono::system_clock::time_point when;  // station clock, when the driver saw the change
  PlcEventKind kind;
  std::string text;
  // InterlockTripped: the PLC's fault word (FaultBit), its causes. The trip may be read before the
  // input that caused it changes in another register's read: the word says what it was.
  std::uint16_t fault_word = 0;
};

class ModbusPlc : public Device {
 public:
  using EventCallback = std::function<void(const PlcEvent&)>;
  using StopCallback = std::function<void(const DeviceFault&)>;

  // Throws std::invalid_argument for options that cannot work (port 0, a zero timeout, ...).
  explicit ModbusPlc(ModbusPlcOptions options = {}, std::string name = "plc");
  ~ModbusPlc() override;

  // Reads discrete inputs and input registers (two requests). Throws DeviceError: "timeout" when
  // the PLC does not reply within response_timeout (or does not accept a connection within
  // connect_timeout), "disconnected" when it cannot be reached (one reconnect is tried first),
  // "protocol" on an exception reply or a malformed frame. Every call is bounded: at most two
  // connects and two attempts of its requests, each within its timeout.
  PlcInputs readInputs();
  PlcOutputs readOutputs();
  // All coils: one request per run of consecutive coil addresses (one for the standard map); an
  // address between the map's coils is never written (on a real PLC it may be another signal).
  void writeOutputs(const PlcOutputs& outputs);
  void setOutput(Coil coil, bool on);
  // Writes the next station heartbeat value and returns it (the watchdog thread also does this).
  std::uint16_t writeHeartbeat();
  // The line's handshake: its request (one read of the holding registers' span) and the cell's
  // answer (one write per run of consecutive cell_* addresses; one for the standard map). Throw
  // DeviceError as readInputs does.
  LineRequest readLineRequest();
  CellAnswer readCellAnswer();
  void writeCellAnswer(const CellAnswer& answer);
  void setPlcWatchdogTimeout(std::chrono::milliseconds timeout);

  // The callbacks run on the watchdog thread (connection events of the API connection: on the
  // calling thread), until disconnect(); what they capture must live until then. They must not call
  // disconnect() or destroy the driver, and should return quickly: the watchdog waits for them.
  // Change events: door, e-stop, light curtain, air, interlock, connection, silence.
  void setEventCallback(EventCallback callback);
  // Called once when the PLC falls silent for longer than silence_limit (fault "plc-silent"): the
  // scan must stop. Re-armed when the PLC answers again.
  void setStopCallback(StopCallback callback);

  std::vector<PlcEvent> events() const;
  // The last state the watchdog thread read, if any.
  std::optional<PlcInputs> lastInputs() const;
  const ModbusPlcOptions& options() const { return options_; }

 protected:
  void connectDevice() override;
  void disconnectDevice() noexcept override;
  DeviceIdentity identifyDevice() override;
  // Reads the inputs; throws DeviceError (without logging it) when the PLC reports a fault.
  void checkDevice() override;

 private:
  struct Impl;
  // Runs one operation on the API connection under its mutex: reconnects first if the connection
  // was lost, retries once after a lost connection, records a fault and throws on failure.
  void request(const char* what, const std::function<void(detail::ModbusClient&)>& operation);
  void watchdogLoop();
  // Compares with the last state the watchdog saw; records and delivers the change events.
  void noteInputs(const PlcInputs& inputs);
  PlcEvent recordEvent(PlcEventKind kind, std::string text, std::uint16_t fault_word = 0);
  void deliver(const std::vector<PlcEvent>& events);
  std::string endpoint() const;

  ModbusPlcOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::drivers::plc
