// IppCmm: what moves the machine (Home, GoTo, ChangeTool), position and head queries, the move
// report daemon and AbortE.
#include "ipp_client_internal.hpp"
#include "stampscan/drivers/cmm/ipp_errors.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace stampscan::drivers::cmm {

namespace {
constexpr double kMinReportInterval = 0.1;  // §6.3.2.7: Time not below 0.1 s, at most 10 reports a second

// The extension item asking the server for its clock in each report (PROTOCOL.md); the prefix
// follows §9.1's scheme for company extensions.
constexpr const char* kDeviceTimeItem = "SS.Time";

// The wire's angles are degrees (§6.1.2); the house's radians.
constexpr double kDegPerRad = 180 / std::numbers::pi;

std::vector<ipp::Argument> xyz(const CmmPosition& p) {
  return {ipp::Argument::call("X", {ipp::Argument::num(p.x)}), ipp::Argument::call("Y", {ipp::Argument::num(p.y)}),
          ipp::Argument::call("Z", {ipp::Argument::num(p.z)})};
}

std::vector<ipp::Argument> xyzQuery() {
  return {ipp::Argument::call("X"), ipp::Argument::call("Y"), ipp::Argument::call("Z")};
}

std::optional<CmmPosition> positionIn(const std::vector<ipp::Argument>& items) {
  const auto x = detail::numberOf(items, "X");
  const auto y = detail::numberOf(items, "Y");
  const auto z = detail::numberOf(items, "Z");
  if (!x || !y || !z) return std::nullopt;
  return CmmPosition{*x, *y, *z};
}

std::int64_t steadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

// Busy while the machine moves on our command; Ready afterwards unless something faulted meanwhile.
class IppCmm::BusyScope {
 public:
  explicit BusyScope(IppCmm& cmm) : cmm_(cmm) { cmm_.setState(DeviceState::Busy); }
  ~BusyScope() {
    if (cmm_.state() == DeviceState::Busy) cmm_.setState(DeviceState::Ready);
  }
  BusyScope(const BusyScope&) = delete;
  BusyScope& operator=(const BusyScope&) = delete;

 private:
  IppCmm& cmm_;
};

MoveOutcome IppCmm::home() {
  auto call = beginCall();
  BusyScope busy(*this);
  return command({.name = "Home", .moves = true}).aborted ? MoveOutcome::Aborted : MoveOutcome::Reached;
}

bool IppCmm::isHomed() {
  auto call = beginCall();
  const Result result = command({.name = "IsHomed"});
  const std::optional<double> homed = result.data.empty() ? std::nullopt : detail::numberOf(result.data[0], "IsHomed");
  if (!homed) badResponse("IsHomed answered without IsHomed(0|1)", result);
  return *homed != 0;
}

void IppCmm::enableUser() {
  auto call = beginCall();
  command({.name = "EnableUser"});
}

void IppCmm::disableUser() {
  auto call = beginCall();
  command({.name = "DisableUser"});
}

ToolOrientation ToolOrientation::fromDegrees(double a_deg, double b_deg, double c_deg) {
  return {a_deg / kDegPerRad, b_deg / kDegPerRad, c_deg / kDegPerRad};
}
double ToolOrientation::aDegrees() const { return a * kDegPerRad; }
double ToolOrientation::bDegrees() const { return b * kDegPerRad; }
double ToolOrientation::cDegrees() const { return c * kDegPerRad; }

std::vector<ipp::Argument> IppCmm::headAxes(const ToolOrientation* orientation) const {
  // Set: Tool.A(deg); queried: Tool.A(). Tool.C only on a head that has it (§6.3.8: ToolAB, ToolABC).
  std::vector<ipp::Argument> axes;
  const auto add = [&](const char* name, double degrees) {
    axes.push_back(orientation != nullptr ? ipp::Argument::call(name, {ipp::Argument::num(degrees)})
                                          : ipp::Argument::call(name));
  };
  add("Tool.A", orientation != nullptr ? orientation->aDegrees() : 0);
  add("Tool.B", orientation != nullptr ? orientation->bDegrees() : 0);
  if (options_.head_has_c) add("Tool.C", orientation != nullptr ? orientation->cDegrees() : 0);
  return axes;
}

std::optional<ToolOrientation> IppCmm::orientationIn(const std::vector<ipp::Argument>& items) const {
  const auto a = detail::numberOf(items, "Tool.A");
  const auto b = detail::numberOf(items, "Tool.B");
  const auto c = options_.head_has_c ? detail::numberOf(items, "Tool.C") : std::optional<double>(0.0);
  if (!a || !b || !c) return std::nullopt;
  return ToolOrientation::fromDegrees(*a, *b, *c);
}

MoveOutcome IppCmm::move(std::vector<ipp::Argument> axes, std::optional<double> speed) {
  if (speed && !(std::isfinite(*speed) && *speed > 0)) throw std::invalid_argument(name() + ": speed must be > 0");
  auto call = beginCall();
  // GoToPar is modal on the CMM (§6.3.6); set it only when this move wants another speed.
  applySpeed(speed.value_or(speed_setting_));
  BusyScope busy(*this);
  const Result result = command({.name = "GoTo", .args = std::move(axes), .moves = true});
  return result.aborted ? MoveOutcome::Aborted : MoveOutcome::Reached;
}

MoveOutcome IppCmm::goTo(const CmmPosition& target, std::optional<double> speed) {
  if (!std::isfinite(target.x) || !std::isfinite(target.y) || !std::isfinite(target.z)) {
    throw std::invalid_argument(name() + ": GoTo target must be finite");
  }
  // The head's axes are not named, so they keep their angles (§6.3.2.12).
  return move(xyz(target), speed);
}

MoveOutcome IppCmm::goTo(const CmmPosition& target, const ToolOrientation& orientation, std::optional<double> speed) {
  if (!std::isfinite(target.x) || !std::isfinite(target.y) || !std::isfinite(target.z)) {
    throw std::invalid_argument(name() + ": GoTo target must be finite");
  }
  if (!std::isfinite(orientation.a) || !std::isfinite(orientation.b) || !std::isfinite(orientation.c)) {
    throw std::invalid_argument(name() + ": GoTo head angles must be finite");
  }
  if (!options_.head_has_c && orientation.c != 0) {
    throw std::invalid_argument(name() + ": the head has no Tool.C axis (IppCmmOptions::head_has_c), yet c != 0");
  }
  // One GoTo for all axes, so that they start and finish together (§6.3.2.12).
  std::vector<ipp::Argument> axes = xyz(target);
  for (ipp::Argument& angle : headAxes(&orientation)) axes.push_back(std::move(angle));
  return move(std::move(axes), speed);
}

CmmPosition IppCmm::position() {
  auto call = beginCall();
  const Result result = command({.name = "Get", .args = xyzQuery()});
  const std::optional<CmmPosition> p = result.data.empty() ? std::nullopt : positionIn(result.data[0]);
  if (!p) badResponse("Get answered without X(), Y(), Z()", result);
  return *p;
}

CmmPose IppCmm::pose() {
  auto call = beginCall();
  std::vector<ipp::Argument> items = xyzQuery();
  for (ipp::Argument& angle : headAxes(nullptr)) items.push_back(std::move(angle));
  const Result result = command({.name = "Get", .args = std::move(items)});
  const std::optional<CmmPosition> p = result.data.empty() ? std::nullopt : positionIn(result.data[0]);
  const std::optional<ToolOrientation> o = result.data.empty() ? std::nullopt : orientationIn(result.data[0]);
  if (!p || !o) badResponse("Get answered without X(), Y(), Z() and the head's angles", result);
  return {*p, *o};
}

void IppCmm::changeTool(const std::string& tool) {
  auto call = beginCall();
  {
    BusyScope busy(*this);
    command({.name = "ChangeTool", .args = {ipp::Argument::str(tool)}, .moves = true});  // std::invalid_argument for a '"'
  }
  // §6.3.6: a new active tool starts with its own default GoToPar values.
  readMotionParameters();
}

// --- Move reports ------------------------------------------------------------------------------

void IppCmm::startMoveReports(double interval_s, MoveReportCallback callback, MoveReportContent content) {
  if (!(interval_s >= kMinReportInterval)) {
    throw std::invalid_argument(name() + ": move report interval must be >= 0.1 s (I++ DME 6.3.2.7)");
  }
  if (!callback) throw std::invalid_argument(name() + ": move reports need a callback");
  {
    // §6.3.2.7: the client ends a running OnMoveReportE before starting another.
    std::unique_lock lock(reports_mutex_);
    const bool running = report_tag_.has_value();
    lock.unlock();
    if (running) stopMoveReports();
  }
  auto call = beginCall();
  std::vector<ipp::Argument> items{ipp::Argument::call("Time", {ipp::Argument::num(interval_s)})};
  for (ipp::Argument& axis : xyzQuery()) items.push_back(std::move(axis));
  const bool with_orientation = content == MoveReportContent::PositionAndOrientation;
  if (with_orientation) {
    for (ipp::Argument& angle : headAxes(nullptr)) items.push_back(std::move(angle));
  }
  if (options_.device_time_in_reports) items.push_back(ipp::Argument::call(kDeviceTimeItem));
  {
    std::lock_guard lock(reports_mutex_);
    report_callback_ = std::make_shared<MoveReportCallback>(std::move(callback));
  }
  try {
    const Result result = command({.name = "OnMoveReportE",
                                   .args = std::move(items),
                                   .event = true,
                                   .daemon = [this, with_orientation](const ipp::Reply& reply) {
                                     onMoveReportLine(reply, with_orientation);
                                   }});
    std::lock_guard lock(reports_mutex_);
    report_tag_ = result.tag;
  } catch (...) {
    std::lock_guard lock(reports_mutex_);
    report_callback_.reset();
    throw;
  }
}

void IppCmm::stopMoveReports() {
  auto call = beginCall();
  std::optional<ipp::Tag> tag;
  {
    std::lock_guard lock(reports_mutex_);
    tag = report_tag_;
  }
  if (!tag) return;
  // StopDaemon (§6.3.1.3) completes only when no more events of the tag follow.
  command({.name = "StopDaemon", .args = {ipp::Argument::name(tag->str())}});
  if (const auto link = channel()) link->removeDaemon(*tag);
  std::lock_guard lock(reports_mutex_);
  report_tag_.reset();
  report_callback_.reset();
}

void IppCmm::onMoveReportLine(const ipp::Reply& reply, bool with_orientation) {
  std::shared_ptr<MoveReportCallback> callback;
  {
    std::lock_guard lock(reports_mutex_);
    callback = report_callback_;
  }
  if (!callback) return;
  MoveReport report;
  report.arrival_steady_ns = steadyNowNs();
  const std::optional<CmmPosition> position = positionIn(reply.data);
  if (!position) {
    fault("protocol", "move report without X(), Y(), Z(): " + ipp::formatArguments(reply.data));
    return;
  }
  report.position = *position;
  if (with_orientation) {
    report.orientation = orientationIn(reply.data);
    if (!report.orientation) {
      fault("protocol", "move report without the head's angles: " + ipp::formatArguments(reply.data));
      return;
    }
  }
  report.device_time_s = detail::numberOf(reply.data, kDeviceTimeItem);
  (*callback)(report);
}

// --- AbortE --------------------------------------------------------------------------------------

std::uint64_t IppCmm::waitWhileAborting(bool wait) {
  std::unique_lock lock(abort_mutex_);
  if (wait) abort_done_.wait(lock, [this] { return !aborting_; });
  return aborts_begun_;
}

bool IppCmm::abortedByUs(const Result& result) {
  std::unique_lock lock(abort_mutex_);
  // Counting abort() calls rather than looking at aborting_: the caller may wake up only after
  // abort() has finished.
  if (aborts_begun_ == result.aborts_before) return false;
  for (const ipp::ErrorReport& e : result.errors) {
    if (e.number != ipp::error::kTransactionAborted) return false;
  }
  // Return only once abort() has cleared the server's error state, so that the caller's next
  // command is not answered 0514 (§6.3.1.5).
  abort_done_.wait(lock, [this] { return !aborting_; });
  return true;
}

void IppCmm::abort() {
  if (!channel()) throw DeviceError(name(), "not-ready", "not connected; call connect()");
  {
    std::unique_lock lock(abort_mutex_);
    if (aborting_) {  // another thread is aborting already; the effect is the same
      abort_done_.wait(lock, [this] { return !aborting_; });
      return;
    }
    aborting_ = true;
    ++aborts_begun_;
  }
  struct Done {
    IppCmm& cmm;
    ~Done() {
      std::lock_guard lock(cmm.abort_mutex_);
      cmm.aborting_ = false;
      cmm.abort_done_.notify_all();
    }
  } done{*this};
  // §6.3.1.5: the server answers every pending transaction first, then AbortE's `%`; the next
  // command must be ClearAllErrors.
  transact({.name = "AbortE", .event = true, .during_abort = true});
  const Result cleared = transact({.name = "ClearAllErrors", .during_abort = true});
  if (!cleared.errors.empty()) throw fault("device-error", ipp::describe(cleared.errors.front()) + " after AbortE()");
  if (state() == DeviceState::Faulted) setState(DeviceState::Ready);
}

}  // namespace stampscan::drivers::cmm
