#include "stampscan/drivers/plc/modbus_plc.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <utility>
#include <vector>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "modbus_client.hpp"

namespace stampscan::drivers::plc {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

const char* toString(PlcEventKind kind) {
  switch (kind) {
    case PlcEventKind::DoorOpened: return "door-opened";
    case PlcEventKind::DoorClosed: return "door-closed";
    case PlcEventKind::EStopBroken: return "e-stop-broken";
    case PlcEventKind::EStopRestored: return "e-stop-restored";
    case PlcEventKind::LightCurtainInterrupted: return "light-curtain-interrupted";
    case PlcEventKind::LightCurtainCleared: return "light-curtain-cleared";
    case PlcEventKind::AirPressureLost: return "air-pressure-lost";
    case PlcEventKind::AirPressureRestored: return "air-pressure-restored";
    case PlcEventKind::InterlockTripped: return "interlock-tripped";
    case PlcEventKind::InterlockCleared: return "interlock-cleared";
    case PlcEventKind::ConnectionLost: return "connection-lost";
    case PlcEventKind::Reconnected: return "reconnected";
    case PlcEventKind::PlcSilent: return "plc-silent";
    case PlcEventKind::PlcAnswering: return "plc-answering";
  }
  return "unknown";
}

struct ModbusPlc::Impl {
  std::mutex api_mutex;                       // serialises every use of `api`
  std::unique_ptr<detail::ModbusClient> api;  // null while disconnected
  bool api_lost = false;  // the API connection was lost; its next connect is a reconnect

  std::thread watchdog;
  std::mutex watchdog_mutex;
  std::condition_variable watchdog_wake;
  bool stop_watchdog = false;

  std::atomic<std::uint16_t> heartbeat{0};  // shared by both connections so the value always moves

  mutable std::mutex events_mutex;  // events, last_inputs and the callbacks
  std::vector<PlcEvent> events;
  std::optional<PlcInputs> last_inputs;
  EventCallback on_event;
  StopCallback on_stop;

  std::uint16_t nextHeartbeat() { return static_cast<std::uint16_t>(heartbeat.fetch_add(1) + 1U); }
};

namespace {

// Reads the whole input state in two requests: the span of the map's discrete inputs and of its
// input registers (an address in a gap is read and ignored).
PlcInputs readInputsFrom(detail::ModbusClient& client, const RegisterMap& map) {
  const AddressSpan bit_span = map.span(RegisterKind::DiscreteInput);
  const AddressSpan reg_span = map.span(RegisterKind::InputRegister);
  std::array<std::uint8_t, kMaxAddressSpan> bits{};
  std::array<std::uint16_t, kMaxAddressSpan> regs{};
  client.readInputBits(bit_span.first, bit_span.count, bits.data());
  client.readInputRegisters(reg_span.first, reg_span.count, regs.data());
  const auto bit = [&](DiscreteInput input) { return bits[map.address(input) - bit_span.first] != 0; };
  const auto reg = [&](InputRegister r) { return regs[map.address(r) - reg_span.first]; };
  PlcInputs in;
  in.door_closed = bit(DiscreteInput::DoorClosed);
  in.e_stop_chain_ok = bit(DiscreteInput::EStopChainOk);
  in.light_curtain_clear = bit(DiscreteInput::LightCurtainClear);
  in.part_clamped = bit(DiscreteInput::PartClamped);
  in.laser_shutter_closed = bit(DiscreteInput::LaserShutterClosed);
  in.air_pressure_ok = bit(DiscreteInput::AirPressureOk);
  in.plc_heartbeat = reg(InputRegister::PlcHeartbeat);
  in.station_heartbeat_echo = reg(InputRegister::StationHeartbeatEcho);
  in.firmware_major = reg(InputRegister::FirmwareMajor);
  in.firmware_minor = reg(InputRegister::FirmwareMinor);
  in.fault_word = reg(InputRegister::FaultWord);
  // An unknown interlock value is taken as tripped: the safe reading.
  in.interlock = reg(InputRegister::InterlockState) == 0 ? InterlockState::Clear
                                                         : InterlockState::Tripped;
  return in;
}

// Which field of PlcOutputs each coil is.
constexpr std::array<std::pair<Coil, bool PlcOutputs::*>, kCoilCount> kOutputFields{{
    {Coil::StackLightGreen, &PlcOutputs::stack_light_green},
    {Coil::StackLightAmber, &PlcOutputs::stack_light_amber},
    {Coil::StackLightRed, &PlcOutputs::stack_light_red},
    {Coil::LaserShutterOpenRequest, &PlcOutputs::laser_shutter_open_request},
    {Coil::ClampRequest, &PlcOutputs::clamp_request},
    {Coil::MotionEnable, &PlcOutputs::motion_enable},
}};

// Coils at consecutive addresses, written in one request.
struct CoilRun {
  std::uint16_t first = 0;
  std::vector<std::uint8_t> values;
};

std::vector<CoilRun> coilRuns(const PlcOutputs& out, const RegisterMap& map) {
  std::array<std::pair<std::uint16_t, bool>, kCoilCount> coils{};
  for (std::size_t i = 0; i < kCoilCount; ++i)
    coils[i] = {map.address(kOutputFields[i].first), out.*kOutputFields[i].second};
  std::sort(coils.begin(), coils.end());
  std::vector<CoilRun> runs;
  for (const auto& [address, on] : coils) {
    if (runs.empty() || runs.back().first + runs.back().values.size() != address) runs.push_back({address, {}});
    runs.back().values.push_back(on ? 1 : 0);
  }
  return runs;
}

// The coils from a read of the map's coil span.
PlcOutputs decode(const std::uint8_t* span_bits, AddressSpan span, const RegisterMap& map) {
  PlcOutputs out;
  for (const auto& [coil, field] : kOutputFields) out.*field = span_bits[map.address(coil) - span.first] != 0;
  return out;
}

std::string millisText(Clock::duration duration) {
  return std::to_string(std::chrono::duration_cast<milliseconds>(duration).count()) + " ms";
}

}  // namespace

namespace {

// Options that cannot work are a programming or config error: refused at construction, not at the
// first scan.
const ModbusPlcOptions& validated(const ModbusPlcOptions& options, const std::string& name) {
  const auto refuse = [&](const std::string& what) {
    throw std::invalid_argument(name + ": invalid PLC options: " + what);
  };
  if (options.host.empty()) refuse("empty host");
  if (options.port < 1 || options.port > 65535)
    refuse("port " + std::to_string(options.port) + " outside 1..65535");
  if (options.unit_id < 0 || options.unit_id > 255)
    refuse("unit id " + std::to_string(options.unit_id) + " outside 0..255");
  if (options.response_timeout < milliseconds(1)) refuse("response_timeout below 1 ms");
  if (options.connect_timeout < milliseconds(1)) refuse("connect_timeout below 1 ms");
  if (options.poll_period < milliseconds(1)) refuse("poll_period below 1 ms");
  if (options.silence_limit < milliseconds(1)) refuse("silence_limit below 1 ms");
  if (const std::string problem = options.registers.problem(); !problem.empty()) refuse("register map: " + problem);
  return options;
}

}  // namespace

ModbusPlc::ModbusPlc(ModbusPlcOptions options, std::string name)
    : Device(std::move(name)),
      options_(validated(options, this->name())),
      impl_(std::make_unique<Impl>()) {}

// The watchdog thread uses this object: stop it before the members go.
ModbusPlc::~ModbusPlc() { disconnectDevice(); }

std::string ModbusPlc::endpoint() const {
  return options_.host + ":" + std::to_string(options_.port) + " (unit " +
         std::to_string(options_.unit_id) + ")";
}

void ModbusPlc::request(const char* what,
                        const std::function<void(detail::ModbusClient&)>& operation) {
  std::vector<PlcEvent> pending;  // delivered after the lock, so a callback may call the driver
  std::optional<DeviceError> error;
  {
    std::lock_guard lock(impl_->api_mutex);
    if (!impl_->api) throw DeviceError(name(), "disconnected", std::string(what) + ": not connected");
    detail::ModbusClient& client = *impl_->api;
    for (int attempt = 1;; ++attempt) {
      try {
        if (client.ensureConnected() && impl_->api_lost) {
          impl_->api_lost = false;
          pending.push_back(recordEvent(PlcEventKind::Reconnected, "reconnected to " + endpoint()));
        }
        operation(client);
        break;
      } catch (const detail::ModbusFailure& failure) {
        // After any failure the stream may still carry a late reply, which would be taken for the
        // answer to the next request: start the next request on a fresh connection.
        client.close();
        if (failure.isConnectionLost() && attempt == 1) {
          if (!impl_->api_lost) {
            impl_->api_lost = true;
            pending.push_back(recordEvent(PlcEventKind::ConnectionLost,
                                          std::string("connection lost: ") + failure.what()));
          }
          continue;  // every request here is idempotent, so one retry on a new connection is safe
        }
        error = fault(failure.code(), std::string(what) + " at " + endpoint() + ": " + failure.what());
        break;
      }
    }
  }
  deliver(pending);
  if (error) throw *error;
}

PlcInputs ModbusPlc::readInputs() {
  PlcInputs inputs;
  request("read inputs", [&](detail::ModbusClient& client) { inputs = readInputsFrom(client, options_.registers); });
  return inputs;
}

PlcOutputs ModbusPlc::readOutputs() {
  const AddressSpan span = options_.registers.span(RegisterKind::Coil);
  std::array<std::uint8_t, kMaxAddressSpan> bits{};
  request("read outputs", [&](detail::ModbusClient& client) {
    client.readBits(span.first, span.count, bits.data());
  });
  return decode(bits.data(), span, options_.registers);
}

void ModbusPlc::writeOutputs(const PlcOutputs& outputs) {
  const std::vector<CoilRun> runs = coilRuns(outputs, options_.registers);
  request("write outputs", [&](detail::ModbusClient& client) {
    for (const CoilRun& run : runs)
      client.writeBits(run.first, static_cast<std::uint16_t>(run.values.size()), run.values.data());
  });
}

void ModbusPlc::setOutput(Coil coil, bool on) {
  request("write output", [&](detail::ModbusClient& client) {
    client.writeBit(options_.registers.address(coil), on);
  });
}

std::uint16_t ModbusPlc::writeHeartbeat() {
  const std::uint16_t value = impl_->nextHeartbeat();
  request("write heartbeat", [&](detail::ModbusClient& client) {
    client.writeRegister(options_.registers.address(HoldingRegister::StationHeartbeat), value);
  });
  return value;
}

namespace {

// The cell_* registers, in the order of CellAnswer's fields.
constexpr std::array<HoldingRegister, 5> kAnswerRegisters{HoldingRegister::CellReady, HoldingRegister::CellBusy,
                                                          HoldingRegister::CellDone, HoldingRegister::CellVerdict,
                                                          HoldingRegister::CellErrorCode};

std::array<std::uint16_t, 5> answerValues(const CellAnswer& a) {
  return {std::uint16_t{a.ready}, std::uint16_t{a.busy}, std::uint16_t{a.done}, static_cast<std::uint16_t>(a.verdict),
          static_cast<std::uint16_t>(a.error)};
}

// The line's handshake registers, read in one request over their span.
class LineRegisters {
 public:
  explicit LineRegisters(const RegisterMap& map)
      : map_(map), span_(map.span(RegisterKind::HoldingRegister, SignalGroup::Line)) {}
  void read(detail::ModbusClient& client) { client.readRegisters(span_.first, span_.count, regs_.data()); }
  std::uint16_t at(HoldingRegister r) const { return regs_[map_.address(r) - span_.first]; }
  std::span<const std::uint16_t, kPartIdRegisters> partId() const {
    return std::span<const std::uint16_t, kPartIdRegisters>(regs_.data() + (map_.address(HoldingRegister::LinePartId) - span_.first),
                                                            kPartIdRegisters);
  }

 private:
  const RegisterMap& map_;
  AddressSpan span_;
  std::array<std::uint16_t, kMaxAddressSpan> regs_{};
};

}  // namespace

LineRequest ModbusPlc::readLineRequest() {
  LineRegisters regs(options_.registers);
  request("read line request", [&](detail::ModbusClient& client) { regs.read(client); });
  LineRequest line;
  line.start = regs.at(HoldingRegister::LineStartRequest) != 0;
  line.program_number = regs.at(HoldingRegister::LineProgramNumber);
  line.part_id = decodePartId(regs.partId());
  return line;
}

CellAnswer ModbusPlc::readCellAnswer() {
  LineRegisters regs(options_.registers);
  request("read cell answer", [&](detail::ModbusClient& client) { regs.read(client); });
  CellAnswer a;
  a.ready = regs.at(HoldingRegister::CellReady) != 0;
  a.busy = regs.at(HoldingRegister::CellBusy) != 0;
  a.done = regs.at(HoldingRegister::CellDone) != 0;
  // A value outside the enums is kept as it is: the caller compares, it does not describe.
  a.verdict = static_cast<LineVerdict>(regs.at(HoldingRegister::CellVerdict));
  a.error = static_cast<LineError>(regs.at(HoldingRegister::CellErrorCode));
  return a;
}

void ModbusPlc::writeCellAnswer(const CellAnswer& answer) {
  // One write per run of consecutive addresses, in address order; an address between them is
  // never written (on a real PLC it may be another signal).
  std::array<std::pair<std::uint16_t, std::uint16_t>, kAnswerRegisters.size()> cells{};
  const auto values = answerValues(answer);
  for (std::size_t i = 0; i < cells.size(); ++i) cells[i] = {options_.registers.address(kAnswerRegisters[i]), values[i]};
  std::sort(cells.begin(), cells.end());
  std::vector<std::pair<std::uint16_t, std::vector<std::uint16_t>>> runs;
  for (const auto& [address, value] : cells) {
    if (runs.empty() || runs.back().first + runs.back().second.size() != address) runs.push_back({address, {}});
    runs.back().second.push_back(value);
  }
  request("write cell answer", [&](detail::ModbusClient& client) {
    for (const auto& [first, run] : runs) client.writeRegisters(first, static_cast<std::uint16_t>(run.size()), run.data());
  });
}

void ModbusPlc::setPlcWatchdogTimeout(milliseconds timeout) {
  if (timeout.count() < 0 || timeout.count() > 0xFFFF)
    throw DeviceError(name(), "invalid-argument",
                      "PLC watchdog timeout " + std::to_string(timeout.count()) +
                          " ms is outside 0..65535 ms");
  request("write watchdog timeout", [&](detail::ModbusClient& client) {
    client.writeRegister(options_.registers.address(HoldingRegister::WatchdogTimeoutMs),
                         static_cast<std::uint16_t>(timeout.count()));
  });
}

void ModbusPlc::setEventCallback(EventCallback callback) {
  std::lock_guard lock(impl_->events_mutex);
  impl_->on_event = std::move(callback);
}

void ModbusPlc::setStopCallback(StopCallback callback) {
  std::lock_guard lock(impl_->events_mutex);
  impl_->on_stop = std::move(callback);
}

std::vector<PlcEvent> ModbusPlc::events() const {
  std::lock_guard lock(impl_->events_mutex);
  return impl_->events;
}

std::optional<PlcInputs> ModbusPlc::lastInputs() const {
  std::lock_guard lock(impl_->events_mutex);
  return impl_->last_inputs;
}

PlcEvent ModbusPlc::recordEvent(PlcEventKind kind, std::string text, std::uint16_t fault_word) {
  PlcEvent event{std::chrono::system_clock::now(), kind, std::move(text), fault_word};
  std::lock_guard lock(impl_->events_mutex);
  impl_->events.push_back(event);
  return event;
}

void ModbusPlc::deliver(const std::vector<PlcEvent>& events) {
  if (events.empty()) return;
  EventCallback callback;
  {
    std::lock_guard lock(impl_->events_mutex);
    callback = impl_->on_event;
  }
  if (!callback) return;
  for (const PlcEvent& event : events) callback(event);
}

void ModbusPlc::connectDevice() {
  {
    std::lock_guard lock(impl_->api_mutex);
    impl_->api = std::make_unique<detail::ModbusClient>(options_.host, options_.port,
                                                        options_.unit_id, options_.response_timeout,
                                                        options_.connect_timeout);
    impl_->api_lost = false;
    try {
      impl_->api->ensureConnected();
    } catch (const detail::ModbusFailure& failure) {
      impl_->api.reset();
      throw fault(failure.code(), std::string(failure.what()) + " (unit " + std::to_string(options_.unit_id) + ")");
    }
  }
  if (options_.plc_watchdog_timeout_ms)
    setPlcWatchdogTimeout(milliseconds(*options_.plc_watchdog_timeout_ms));
  if (options_.watchdog) {
    // Left unjoined only when a callback disconnected from the watchdog thread itself.
    if (impl_->watchdog.joinable()) impl_->watchdog.join();
    {
      std::lock_guard lock(impl_->watchdog_mutex);
      impl_->stop_watchdog = false;
    }
    impl_->watchdog = std::thread([this] {
      try {
        watchdogLoop();
      } catch (const std::exception& e) {  // only if a context cannot even be allocated
        fault("watchdog", std::string("PLC watchdog stopped: ") + e.what());
      }
    });
  }
}

void ModbusPlc::disconnectDevice() noexcept {
  {
    std::lock_guard lock(impl_->watchdog_mutex);
    impl_->stop_watchdog = true;
  }
  impl_->watchdog_wake.notify_all();
  // A callback that disconnects would join its own thread; it is documented as not allowed, and
  // here it only asks the thread to stop, leaving the join to the next disconnect or destructor.
  if (impl_->watchdog.joinable() && impl_->watchdog.get_id() != std::this_thread::get_id())
    impl_->watchdog.join();
  std::lock_guard lock(impl_->api_mutex);
  impl_->api.reset();
  std::lock_guard events_lock(impl_->events_mutex);
  impl_->last_inputs.reset();
}

DeviceIdentity ModbusPlc::identifyDevice() {
  const PlcInputs inputs = readInputs();
  DeviceIdentity id;
  id.family = "plc";
  id.model = "Modbus TCP unit " + std::to_string(options_.unit_id);
  id.firmware =
      std::to_string(inputs.firmware_major) + "." + std::to_string(inputs.firmware_minor);
  id.address = options_.host + ":" + std::to_string(options_.port);
  return id;
}

void ModbusPlc::checkDevice() {
  const PlcInputs inputs = readInputs();
  // Reported, not logged: a health check must not fill the fault log with the door's state.
  if (inputs.fault_word != 0)
    throw DeviceError(name(), "device-error",
                      "PLC reports faults: " + describeFaultWord(inputs.fault_word));
}

void ModbusPlc::noteInputs(const PlcInputs& in) {
  std::vector<PlcEvent> pending;
  std::optional<PlcInputs> before;
  {
    std::lock_guard lock(impl_->events_mutex);
    before = impl_->last_inputs;
    impl_->last_inputs = in;
  }
  if (!before) return;  // the first read is the baseline; the caller checks the state it starts in
  const auto edge = [&](bool was, bool now, PlcEventKind off, PlcEventKind on, const char* off_text,
                        const char* on_text) {
    if (was == now) return;
    pending.push_back(now ? recordEvent(on, on_text) : recordEvent(off, off_text));
  };
  edge(before->door_closed, in.door_closed, PlcEventKind::DoorOpened, PlcEventKind::DoorClosed,
       "door opened", "door closed");
  edge(before->e_stop_chain_ok, in.e_stop_chain_ok, PlcEventKind::EStopBroken,
       PlcEventKind::EStopRestored, "e-stop chain broken", "e-stop chain restored");
  edge(before->light_curtain_clear, in.light_curtain_clear, PlcEventKind::LightCurtainInterrupted,
       PlcEventKind::LightCurtainCleared, "light curtain interrupted", "light curtain clear");
  edge(before->air_pressure_ok, in.air_pressure_ok, PlcEventKind::AirPressureLost,
       PlcEventKind::AirPressureRestored, "air pressure low", "air pressure restored");
  if (before->interlockTripped() != in.interlockTripped()) {
    if (in.interlockTripped()) {
      const std::string causes = describeFaultWord(in.fault_word);
      pending.push_back(recordEvent(
          PlcEventKind::InterlockTripped,
          "interlock tripped (" + causes + "): laser shutter closed, motion enable dropped", in.fault_word));
      fault("interlock", "PLC interlock tripped: " + causes);
    } else {
      pending.push_back(recordEvent(PlcEventKind::InterlockCleared, "interlock clear"));
    }
  }
  deliver(pending);
}

void ModbusPlc::watchdogLoop() {
  // This thread's own context and connection (see the class comment).
  detail::ModbusClient client(options_.host, options_.port, options_.unit_id,
                              options_.response_timeout, options_.connect_timeout);
  Clock::time_point last_answer = Clock::now();
  bool silent = false;
  bool lost = false;
  for (;;) {
    const Clock::time_point deadline = last_answer + options_.silence_limit;
    std::vector<PlcEvent> pending;
    bool answered = false;
    try {
      // A request never waits past the silence deadline, so the stop comes on time even when the
      // PLC swallows a request; once silent, the normal timeout applies.
      const Clock::duration left = deadline - Clock::now();
      client.setResponseTimeout(std::chrono::duration_cast<std::chrono::microseconds>(
          silent ? Clock::duration(options_.response_timeout)
                 : std::clamp<Clock::duration>(left, milliseconds(1), options_.response_timeout)));
      client.setConnectTimeout(silent ? options_.connect_timeout
                                      : std::clamp(std::chrono::ceil<milliseconds>(left), milliseconds(1),
                                                   options_.connect_timeout));
      if (client.ensureConnected() && lost) {
        lost = false;
        pending.push_back(recordEvent(PlcEventKind::Reconnected,
                                      "watchdog reconnected to " + endpoint()));
      }
      client.writeRegister(options_.registers.address(HoldingRegister::StationHeartbeat), impl_->nextHeartbeat());
      const PlcInputs inputs = readInputsFrom(client, options_.registers);
      answered = true;
      last_answer = Clock::now();
      if (silent) {
        silent = false;
        pending.push_back(recordEvent(PlcEventKind::PlcAnswering, "PLC answers again"));
      }
      deliver(pending);
      pending.clear();
      noteInputs(inputs);
    } catch (const detail::ModbusFailure& failure) {
      client.close();  // as in request(): a late reply must not answer the next request
      if (failure.isConnectionLost() && !lost) {
        lost = true;
        pending.push_back(recordEvent(PlcEventKind::ConnectionLost,
                                      std::string("watchdog connection lost: ") + failure.what()));
      }
      if (!silent && Clock::now() >= deadline) {
        silent = true;
        const std::string text = "no answer from " + endpoint() + " for " +
                                 millisText(Clock::now() - last_answer) + " (limit " +
                                 millisText(options_.silence_limit) + "): " + failure.what();
        pending.push_back(recordEvent(PlcEventKind::PlcSilent, text));
        fault("plc-silent", text);
        StopCallback on_stop;
        {
          std::lock_guard lock(impl_->events_mutex);
          on_stop = impl_->on_stop;
        }
        if (on_stop) on_stop(DeviceFault{std::chrono::system_clock::now(), "plc-silent", text});
      }
    }
    deliver(pending);
    // After an answer, wait one poll period; while failing, also wake at the silence deadline.
    Clock::time_point wake = Clock::now() + options_.poll_period;
    if (!answered && !silent) wake = std::min(wake, last_answer + options_.silence_limit);
    std::unique_lock lock(impl_->watchdog_mutex);
    if (impl_->watchdog_wake.wait_until(lock, wake, [&] { return impl_->stop_watchdog; })) return;
  }
}

}  // namespace stampscan::drivers::plc
