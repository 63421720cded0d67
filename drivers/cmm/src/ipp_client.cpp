// IppCmm: session, transactions, error recovery, properties and tools. Motion, reports and AbortE
// are in ipp_client_motion.cpp.
#include "ipp_client_internal.hpp"
#include "stampscan/drivers/cmm/ipp_errors.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::drivers::cmm {

using detail::IppChannel;
using detail::WaitResult;

namespace {
constexpr std::chrono::milliseconds kEndSessionTimeout{1000};  // disconnecting must not hang on a silent CMM

std::string milliseconds(std::chrono::milliseconds d) { return std::to_string(d.count()) + " ms"; }
}  // namespace

IppError::IppError(const std::string& device, ipp::ErrorReport report, std::string info)
    : DeviceError(device, "device-error", ipp::describe(report) + (info.empty() ? "" : " (" + info + ")")),
      report_(std::move(report)),
      info_(std::move(info)) {}

IppCmm::IppCmm(IppCmmOptions options, std::string name) : Device(std::move(name)), options_(std::move(options)) {}

IppCmm::~IppCmm() { disconnect(); }

std::shared_ptr<IppChannel> IppCmm::channel() const {
  std::lock_guard lock(channel_mutex_);
  return channel_;
}

void IppCmm::markUnresponsive() {
  std::lock_guard lock(channel_mutex_);
  responsive_ = false;
}

std::unique_lock<std::mutex> IppCmm::beginCall() {
  std::unique_lock lock(call_mutex_);
  const DeviceState s = state();
  if (s == DeviceState::Disconnected) throw DeviceError(name(), "not-ready", "not connected; call connect()");
  if (s == DeviceState::Faulted) {
    throw DeviceError(name(), "not-ready", "faulted; call clearAllErrors() or connect() first");
  }
  return lock;
}

// --- Session -----------------------------------------------------------------------------------

void IppCmm::connectDevice() {
  std::lock_guard call(call_mutex_);
  IppChannel::Callbacks callbacks;
  callbacks.lost = [this](const std::string& why) { fault("disconnected", why); };
  callbacks.garbled = [this](const std::string& what) { fault("protocol", what); };
  callbacks.unsolicited = [this](const ipp::Reply& reply) {
    if (reply.kind != ipp::ReplyKind::Error) return;  // server events other than errors: none we use
    {
      std::lock_guard lock(channel_mutex_);
      unsolicited_.push_back(reply.error);
    }
    if (ipp::needsClearAllErrors(reply.error.severity)) fault("device-error", "unsolicited " + ipp::describe(reply.error));
  };
  auto fresh = std::make_shared<IppChannel>(options_.host, options_.port, options_.connect_timeout,
                                            options_.reply_timeout, std::move(callbacks));
  {
    std::lock_guard lock(channel_mutex_);
    channel_ = std::move(fresh);
    responsive_ = true;
  }
  {
    std::lock_guard lock(reports_mutex_);
    report_tag_.reset();  // daemons do not survive a connection (§6.3.1.1: none pending at StartSession)
    report_callback_.reset();
  }
  command({.name = "StartSession"});
  readMotionParameters();
}

void IppCmm::disconnectDevice() noexcept {
  std::shared_ptr<IppChannel> old;
  bool polite = false;
  {
    std::lock_guard lock(channel_mutex_);
    old = std::move(channel_);
    polite = responsive_;
    responsive_ = false;
  }
  if (!old) return;
  if (polite && !old->lost()) {
    // EndSession (§6.3.1.2) stops our daemons on the server; a CMM that does not answer is closed anyway.
    try {
      const auto transaction = old->send("EndSession", {}, false);
      old->wait(*transaction, std::chrono::steady_clock::now() + std::min(options_.reply_timeout, kEndSessionTimeout));
    } catch (const std::exception&) {
    }
  }
  old->close();
  std::lock_guard lock(reports_mutex_);
  report_tag_.reset();
  report_callback_.reset();
}

DeviceIdentity IppCmm::identifyDevice() {
  std::lock_guard call(call_mutex_);
  DeviceIdentity id;
  id.family = "cmm";
  id.address = options_.host + ":" + std::to_string(options_.port);
  // GetDMEVersion is new in 1.4 (§6.3.1.14); an older server answers 0501, which is no fault.
  Result version = transact({.name = "GetDMEVersion"});
  if (version.errors.empty() && !version.data.empty() && !version.data[0].empty() &&
      version.data[0][0].isCall("DMEVersion") && version.data[0][0].args.size() == 1) {
    id.firmware = "I++ DME " + version.data[0][0].args[0].text;
  } else {
    id.firmware = "I++ DME before 1.4";
    if (!version.errors.empty()) command({.name = "ClearAllErrors"});
  }
  const Result machine = command({.name = "GetMachineClass"});  // §6.3.2.8
  if (!machine.data.empty() && !machine.data[0].empty() && machine.data[0][0].isCall("GetMachineClass") &&
      machine.data[0][0].args.size() == 1) {
    id.model = machine.data[0][0].args[0].text;
  }
  return id;
}

void IppCmm::checkDevice() {
  std::lock_guard call(call_mutex_);
  const Result status = command({.name = "GetErrStatusE", .event = true});
  const std::optional<double> in_error = status.data.empty() ? std::nullopt : detail::numberOf(status.data[0], "ErrStatus");
  if (!in_error) badResponse("GetErrStatusE answered without ErrStatus(...)", status);
  if (*in_error != 0) throw fault("device-error", "the CMM reports an error state (GetErrStatusE)");
}

// --- Transactions and recovery -----------------------------------------------------------------

IppCmm::Result IppCmm::transact(const Request& request) {
  const std::shared_ptr<IppChannel> link = channel();
  if (!link) throw DeviceError(name(), "disconnected", "not connected");
  const std::uint64_t aborts_before = waitWhileAborting(!request.during_abort);
  const auto transaction = link->send(request.name, request.args, request.event, request.daemon);
  const std::chrono::milliseconds limit = request.moves ? options_.motion_timeout : options_.reply_timeout;
  switch (link->wait(*transaction, std::chrono::steady_clock::now() + limit)) {
    case WaitResult::Complete: break;
    case WaitResult::Timeout:
      markUnresponsive();
      throw fault("timeout", "no answer from the CMM at " + options_.host + ":" + std::to_string(options_.port) +
                                 " to \"" + transaction->line + "\" within " + milliseconds(limit));
    case WaitResult::Lost:
      // The reader thread has recorded the "disconnected" fault (unless we closed on purpose).
      throw DeviceError(name(), "disconnected", "connection to the CMM at " + options_.host + ":" +
                                                    std::to_string(options_.port) + " lost during \"" +
                                                    transaction->line + "\": " + link->lostReason());
  }
  Result result;
  result.aborts_before = aborts_before;
  result.tag = transaction->tag;
  result.line = transaction->line;
  result.data = transaction->data;
  for (const ipp::ErrorReport& e : transaction->errors) {
    (ipp::needsClearAllErrors(e.severity) ? result.errors : result.warnings).push_back(e);
  }
  if (request.daemon && !result.errors.empty()) link->removeDaemon(transaction->tag);  // no daemon was made
  return result;
}

IppCmm::Result IppCmm::command(const Request& request) {
  Result result = transact(request);
  if (result.errors.empty()) return result;
  if (abortedByUs(result)) {
    result.aborted = true;
    return result;
  }
  recoverAndThrow(result);
}

// The recovery sequence of §6.2.5 and §8: the error is recorded as a fault, GetErrorInfo explains it,
// ClearAllErrors lets the server go on; when that works the driver is Ready again.
void IppCmm::recoverAndThrow(const Result& result) {
  // A server in the error state answers 0511 then 0514 (§6.3.1.7); the first error names the cause.
  const ipp::ErrorReport& cause = result.errors.front();
  fault("device-error", ipp::describe(cause) + ", answering \"" + result.line + "\"");
  std::string info;
  try {
    const Result explained = transact({.name = "GetErrorInfo", .args = {ipp::Argument::num(cause.number)}, .during_abort = true});
    if (!explained.data.empty() && !explained.data[0].empty()) info = explained.data[0][0].text;
    const Result cleared = transact({.name = "ClearAllErrors", .during_abort = true});
    if (cleared.errors.empty()) setState(DeviceState::Ready);
  } catch (const DeviceError&) {
    // Timeout or lost connection during recovery: that fault is recorded, the driver stays Faulted.
  }
  throw IppError(name(), cause, info);
}

[[noreturn]] void IppCmm::badResponse(const std::string& what, const Result& result) {
  throw fault("protocol", what + " (to \"" + result.line + "\")");
}

void IppCmm::clearAllErrors() {
  std::lock_guard call(call_mutex_);
  if (!channel()) throw DeviceError(name(), "not-ready", "not connected; call connect()");
  command({.name = "ClearAllErrors"});
  if (state() == DeviceState::Faulted) setState(DeviceState::Ready);
}

std::string IppCmm::errorInfo(int error_number) {
  auto call = beginCall();
  const Result result = command({.name = "GetErrorInfo", .args = {ipp::Argument::num(error_number)}});
  if (result.data.empty() || result.data[0].empty()) badResponse("GetErrorInfo answered no data", result);
  return result.data[0][0].kind == ipp::Argument::Kind::String ? result.data[0][0].text
                                                               : ipp::formatArguments(result.data[0]);
}

std::vector<ipp::ErrorReport> IppCmm::unsolicitedErrors() const {
  std::lock_guard lock(channel_mutex_);
  return unsolicited_;
}

// --- Properties and tools ----------------------------------------------------------------------

double IppCmm::readProperty(const std::string& property) {
  const Result result = command({.name = "GetProp", .args = {ipp::Argument::call(property)}});  // §6.3.1.9
  const std::optional<double> value = result.data.empty() ? std::nullopt : detail::numberOf(result.data[0], property);
  if (!value) badResponse("GetProp answered without " + property + "(number)", result);
  return *value;
}

double IppCmm::writeProperty(const std::string& property, double value) {
  if (!std::isfinite(value) || value <= 0) throw std::invalid_argument(property + " must be positive and finite");
  const Result result = command({.name = "SetProp", .args = {ipp::Argument::call(property, {ipp::Argument::num(value)})}});
  // §6.3.6: out of range, the CMM takes its Min or Max and warns 0504; ask what it took.
  for (const ipp::ErrorReport& w : result.warnings) {
    if (w.number == ipp::error::kArgumentOutOfRange) return readProperty(property);
  }
  return value;
}

void IppCmm::readMotionParameters() {
  cmm_speed_ = readProperty("Tool.GoToPar.Speed");
  speed_setting_ = cmm_speed_;
}

void IppCmm::applySpeed(double mm_per_s) {
  if (mm_per_s == cmm_speed_) return;
  cmm_speed_ = writeProperty("Tool.GoToPar.Speed", mm_per_s);
}

double IppCmm::setSpeed(double mm_per_s) {
  auto call = beginCall();
  cmm_speed_ = writeProperty("Tool.GoToPar.Speed", mm_per_s);
  speed_setting_ = cmm_speed_;
  return cmm_speed_;
}

double IppCmm::speed() {
  auto call = beginCall();
  cmm_speed_ = readProperty("Tool.GoToPar.Speed");
  return cmm_speed_;
}

double IppCmm::setAcceleration(double mm_per_s2) {
  auto call = beginCall();
  return writeProperty("Tool.GoToPar.Accel", mm_per_s2);
}

double IppCmm::acceleration() {
  auto call = beginCall();
  return readProperty("Tool.GoToPar.Accel");
}

std::string IppCmm::currentTool() {
  auto call = beginCall();
  const Result result = command({.name = "GetProp", .args = {ipp::Argument::call("Tool.Name")}});
  const ipp::Argument* name_call = result.data.empty() ? nullptr : detail::findCall(result.data[0], "Tool.Name");
  if (name_call == nullptr || name_call->args.size() != 1 || name_call->args[0].kind == ipp::Argument::Kind::Number) {
    badResponse("GetProp answered without Tool.Name(\"...\")", result);
  }
  return name_call->args[0].text;
}

std::vector<std::string> IppCmm::tools() {
  auto call = beginCall();
  const Result result = command({.name = "EnumTools"});
  std::vector<std::string> names;
  for (const std::vector<ipp::Argument>& line : result.data) {
    if (line.size() != 1 || line[0].kind != ipp::Argument::Kind::String) badResponse("EnumTools answered a non-name", result);
    names.push_back(line[0].text);
  }
  return names;
}

}  // namespace stampscan::drivers::cmm
