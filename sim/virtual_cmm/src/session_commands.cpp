// The commands of the virtual CMM's normal queue, run by the session's executor thread. Each checks
// its arguments the way the spec lists them and throws CommandFailure with the §8.2 number.
#include "ipp_session.hpp"

#include "stampscan/drivers/cmm/ipp_errors.hpp"

#include <algorithm>
#include <cmath>
#include <string_view>
#include <sstream>

namespace stampscan::sim::detail {

namespace error = ipp::error;

namespace {

void requireNoArguments(const ipp::Command& c) {
  if (!c.args.empty()) throw CommandFailure(error::kIncorrectArguments, c.name + "() takes no arguments");
}

const std::string& stringArgument(const ipp::Command& c) {
  if (c.args.size() != 1 || c.args[0].kind != ipp::Argument::Kind::String) {
    throw CommandFailure(error::kIncorrectArguments, c.name + "(\"name\") takes one string");
  }
  return c.args[0].text;
}

bool isNumberCall(const ipp::Argument& a) {
  return a.kind == ipp::Argument::Kind::Call && a.args.size() == 1 && a.args[0].kind == ipp::Argument::Kind::Number;
}

// X, Y, Z, Tool.A, Tool.B, Tool.C -> 0..5 (MachinePose::axis); -1 for anything else.
int axisIndex(const ipp::Argument& a) {
  if (a.kind != ipp::Argument::Kind::Call) return -1;
  const auto it = std::find(kAxisNames.begin(), kAxisNames.end(), std::string_view(a.text));
  return it == kAxisNames.end() ? -1 : static_cast<int>(it - kAxisNames.begin());
}

// Axes this CartCMM does not have: a rotary table's (§6.3.3.13) and bare A, B, C, which §6.3.8 only
// knows as the tool's Tool.A, Tool.B, Tool.C.
bool isAbsentAxis(const std::string& name) { return name == "A" || name == "B" || name == "C" || name == "R"; }

std::string where(const MachinePose& p) {
  std::ostringstream text;
  for (std::size_t i = 0; i < 6; ++i) text << (i == 0 ? "" : ", ") << kAxisNames[i] << "(" << p.axis(i) << ")";
  return text.str();
}

ipp::Argument flag(const char* name, bool value) { return ipp::Argument::call(name, {ipp::Argument::num(value ? 1 : 0)}); }

}  // namespace

void IppSession::dispatch(const ipp::Command& c, Responder& out) {
  using Handler = void (IppSession::*)(const ipp::Command&, Responder&);
  static const std::map<std::string, Handler, std::less<>> kHandlers{
      {"StartSession", &IppSession::startSession},   {"EndSession", &IppSession::endSession},
      {"StopDaemon", &IppSession::stopDaemon},       {"StopAllDaemons", &IppSession::stopAllDaemons},
      {"ClearAllErrors", &IppSession::clearAllErrors}, {"GetErrorInfo", &IppSession::getErrorInfo},
      {"GetXtdErrStatus", &IppSession::getXtdErrStatus}, {"Home", &IppSession::home},
      {"GoTo", &IppSession::goTo},                   {"Get", &IppSession::get},
      {"GetProp", &IppSession::getProp},             {"SetProp", &IppSession::setProp},
      {"ChangeTool", &IppSession::changeTool},       {"SetTool", &IppSession::setTool},
      {"FindTool", &IppSession::findTool},           {"EnumTools", &IppSession::enumTools},
      {"EnableUser", &IppSession::userCommand},      {"DisableUser", &IppSession::userCommand},
      {"IsUserEnabled", &IppSession::userCommand},   {"IsHomed", &IppSession::simpleQuery},
      {"GetMachineClass", &IppSession::simpleQuery}, {"GetDMEVersion", &IppSession::simpleQuery},
  };
  if (const auto it = kHandlers.find(c.name); it != kHandlers.end()) {
    (this->*(it->second))(c, out);
    return;
  }
  if (c.name == "AbortE" || c.name == "GetErrStatusE" || c.name == "GetPropE" || c.name == "OnMoveReportE") {
    throw CommandFailure(error::kProtocolError, c.name + " is a fast-queue command: send it with an event tag (6.2.1)");
  }
  throw CommandFailure(error::kUnsupportedCommand, c.name + " is not supported by the virtual CMM");
}

// --- Session, daemons, errors (§6.3.1) -----------------------------------------------------------

void IppSession::startSession(const ipp::Command& c, Responder&) {
  requireNoArguments(c);
  std::lock_guard lock(mutex_);
  if (session_active_) {
    throw CommandFailure(error::kProtocolError, "a session is active already: send EndSession() first (6.3.1)");
  }
  // §6.3.1.1: no daemons from before, and an implicit ClearAllErrors.
  session_active_ = true;
  session_start_ = Clock::now();
  error_state_ = false;
  errors_.clear();
  daemon_.reset();
  found_tool_ = "UnDefTool";
}

void IppSession::endSession(const ipp::Command& c, Responder&) {
  requireNoArguments(c);
  std::lock_guard lock(mutex_);
  session_active_ = false;  // §6.3.1: without a session this does nothing, and that is fine
  daemon_.reset();          // §6.3.1.2: no events after EndSession completes
}

void IppSession::stopDaemon(const ipp::Command& c, Responder&) {
  if (c.args.size() != 1 || c.args[0].kind != ipp::Argument::Kind::Name) {
    throw CommandFailure(error::kIncorrectArguments, "StopDaemon(E0001..E9999) takes one event tag");
  }
  std::optional<ipp::Tag> tag;
  try {
    tag = ipp::parseTag(c.args[0].text);
  } catch (const ipp::ProtocolError&) {
  }
  if (!tag || !tag->isEvent() || tag->isServerEvent()) {
    throw CommandFailure(error::kBadArgument, c.args[0].text + " is not an event tag");
  }
  std::lock_guard lock(mutex_);
  if (!daemon_ || daemon_->tag != *tag) {
    throw CommandFailure(error::kDaemonDoesNotExist, "no daemon runs on " + tag->str());
  }
  daemon_.reset();
}

void IppSession::stopAllDaemons(const ipp::Command& c, Responder& out) {
  requireNoArguments(c);
  bool had_daemon = false;
  {
    std::lock_guard lock(mutex_);
    had_daemon = daemon_.has_value();
    daemon_.reset();
  }
  if (!had_daemon) out.error(error::kNoDaemonsActive, "StopAllDaemons() found no daemon");  // a warning, class 1
}

void IppSession::clearAllErrors(const ipp::Command& c, Responder&) {
  requireNoArguments(c);
  std::lock_guard lock(mutex_);
  error_state_ = false;
  errors_.clear();
}

void IppSession::getErrorInfo(const ipp::Command& c, Responder& out) {
  if (c.args.size() != 1 || c.args[0].kind != ipp::Argument::Kind::Number || c.args[0].number < 0 ||
      c.args[0].number > 9999 || std::floor(c.args[0].number) != c.args[0].number) {
    throw CommandFailure(error::kIncorrectArguments, "GetErrorInfo(number) takes one error number 0-9999");
  }
  const int number = static_cast<int>(c.args[0].number);
  const ipp::ErrorDefinition* definition = ipp::findError(number);
  std::string text = definition != nullptr ? std::string(definition->text) : "not an I++ DME error number";
  {
    std::lock_guard lock(mutex_);
    if (const auto it = error_info_.find(number); it != error_info_.end()) text += ": " + it->second;
  }
  // Within the line limit of §6.2 whatever was recorded: `TAG # "text"` adds 10 characters.
  constexpr std::size_t kMaxText = ipp::kMaxLineLength - 10;
  if (text.size() > kMaxText) text = text.substr(0, kMaxText - 3) + "...";
  out.data({ipp::Argument::str(ipp::sanitizeText(text))});
}

void IppSession::getXtdErrStatus(const ipp::Command& c, Responder& out) {
  requireNoArguments(c);
  bool user = false;
  std::vector<ipp::ErrorReport> errors;
  {
    std::lock_guard lock(mutex_);
    user = user_enabled_;
    errors = errors_;
  }
  // §6.3.2.10: status lines, then the errors.
  out.data({flag("IsHomed", machine_.homed())});
  out.data({flag("IsUserEnabled", user)});
  for (const ipp::ErrorReport& e : errors) {
    out.data({ipp::Argument::call("Error", {ipp::Argument::num(e.severity), ipp::Argument::num(e.number),
                                            ipp::Argument::str(e.method), ipp::Argument::str(e.text)})});
  }
}

// --- Motion (§6.3.2.1, §6.3.2.12) and position (§6.3.2.11) ---------------------------------------

void IppSession::home(const ipp::Command& c, Responder&) {
  requireNoArguments(c);
  {
    std::lock_guard lock(mutex_);
    user_enabled_ = false;  // §6.3.2.4: moving commands disable the user
  }
  // Homing moves the ram; the head keeps its angles.
  if (!runMove({machine_.config().home_position, machine_.pose(Clock::now()).abc})) {
    throw CommandFailure(error::kTransactionAborted, "AbortE stopped Home() at " + where(machine_.pose(Clock::now())));
  }
  machine_.setHomed();
}

void IppSession::goTo(const ipp::Command& c, Responder&) {
  if (c.args.empty()) throw CommandFailure(error::kIncorrectArguments, "GoTo needs X(x), Y(y), Z(z) or Tool.A(a), ...");
  // §6.3.2.12: axes not named keep their value, the head's as much as the ram's.
  MachinePose target = machine_.pose(Clock::now());
  std::array<bool, 6> named{};
  for (const ipp::Argument& a : c.args) {
    const int axis = axisIndex(a);
    if (axis < 0) {
      if (a.kind == ipp::Argument::Kind::Call && isAbsentAxis(a.text)) {
        throw CommandFailure(error::kArgumentNotSupported, a.text + ": this CartCMM has no such axis");
      }
      throw CommandFailure(error::kArgumentNotRecognized, ipp::formatArgument(a) + " is not an argument of GoTo");
    }
    if (a.args.empty()) throw CommandFailure(error::kBadContext, a.text + "() without a value belongs in Get (6.3.3.5)");
    if (!isNumberCall(a)) throw CommandFailure(error::kBadArgument, a.text + "(...) takes one number");
    if (named[axis]) throw CommandFailure(error::kIncorrectArguments, a.text + " named twice (6.1.3)");
    named[static_cast<std::size_t>(axis)] = true;
    target.axis(static_cast<std::size_t>(axis)) = a.args[0].number;
  }
  if (!machine_.homed()) throw CommandFailure(error::kUnableToMove, "not homed: send Home() first (6.3.2.1)");
  // §6.3.3.9: out of limits, the machine does not move at all.
  if (const std::string problem = machine_.travelProblem(target.xyz); !problem.empty()) {
    throw CommandFailure(error::kMachineLimit, problem);
  }
  // §8.2 has one error for an angle the head cannot take, 2505 (class 2: the client can repair
  // it). It serves for an indexing head's off-grid angle too: 1004 is fatal (class 9), and 0509
  // is for arguments that are malformed rather than unreachable.
  if (const std::string problem = machine_.headProblem(target.abc); !problem.empty()) {
    throw CommandFailure(error::kAngleOutOfRange, problem);
  }
  target.abc = machine_.headTarget(target.abc);
  {
    std::lock_guard lock(mutex_);
    user_enabled_ = false;
  }
  if (!runMove(target)) {
    throw CommandFailure(error::kTransactionAborted, "AbortE stopped GoTo at " + where(machine_.pose(Clock::now())));
  }
}

void IppSession::get(const ipp::Command& c, Responder& out) {
  if (c.args.empty()) throw CommandFailure(error::kIncorrectArguments, "Get needs X(), Y(), Z() or Tool.A(), ...");
  const MachinePose pose = machine_.pose(Clock::now());  // one instant for every item
  std::vector<ipp::Argument> items;
  std::array<bool, 6> named{};
  for (const ipp::Argument& a : c.args) {
    const int axis = axisIndex(a);
    if (axis < 0) {
      if (a.kind == ipp::Argument::Kind::Call && isAbsentAxis(a.text)) {
        throw CommandFailure(error::kArgumentNotSupported, a.text + ": this CartCMM has no such axis");
      }
      throw CommandFailure(error::kBadArgument, ipp::formatArgument(a) + " is not an argument of Get");
    }
    if (!a.args.empty()) throw CommandFailure(error::kBadContext, a.text + "(value) belongs in GoTo (6.3.3.9)");
    if (named[axis]) throw CommandFailure(error::kIncorrectArguments, a.text + " named twice (6.1.3)");
    named[static_cast<std::size_t>(axis)] = true;
    items.push_back(ipp::Argument::call(a.text, {ipp::Argument::num(pose.axis(static_cast<std::size_t>(axis)))}));
  }
  out.data(std::move(items));  // §6.2.2.2: exactly the data asked for, in that order
}

// --- Properties (§6.3.1.9, §6.3.1.11, §6.3.6, §6.3.10) -------------------------------------------

ipp::Argument IppSession::propertyValue(const ipp::Argument& property) const {
  if (property.kind != ipp::Argument::Kind::Call || !property.args.empty()) {
    throw CommandFailure(error::kIncorrectArguments, "GetProp takes properties without values, e.g. Tool.Name()");
  }
  const std::string& name = property.text;
  const bool found_tool = name.rfind("FoundTool.", 0) == 0;
  if (!found_tool && name.rfind("Tool.", 0) != 0) throw CommandFailure(error::kBadProperty, name + " is not a property");
  const std::string rest = name.substr(found_tool ? 10 : 5);
  std::string tool = machine_.activeToolName();
  if (found_tool) {
    std::lock_guard lock(mutex_);
    tool = found_tool_;
  }
  if (rest == "Name") return ipp::Argument::call(name, {ipp::Argument::str(tool)});
  // §6.3.8 names Get and OnReport for the head's angles; GetProp(Tool.A()) answers the same, as
  // clients ask for them as tool properties too.
  if (!found_tool && (rest == "A" || rest == "B" || rest == "C")) {
    const MachinePose pose = machine_.pose(Clock::now());
    return ipp::Argument::call(name, {ipp::Argument::num(pose.abc[rest == "A" ? 0 : rest == "B" ? 1 : 2])});
  }
  if (tool == "UnDefTool") throw CommandFailure(error::kToolNotDefined, "FoundTool is not set: FindTool() first");
  const bool active = tool == machine_.activeToolName();  // other tools hold their defaults (§6.3.6)
  const VirtualCmmConfig& k = machine_.config();
  const std::map<std::string, double> values{
      {"GoToPar.Speed", active ? machine_.speed() : k.default_speed},
      {"GoToPar.Speed.Act", active ? machine_.speed() : k.default_speed},
      {"GoToPar.Speed.Max", k.max_speed},
      {"GoToPar.Speed.Min", k.min_speed},
      {"GoToPar.Speed.Def", k.default_speed},
      {"GoToPar.Accel", active ? machine_.accel() : k.default_accel},
      {"GoToPar.Accel.Act", active ? machine_.accel() : k.default_accel},
      {"GoToPar.Accel.Max", k.max_accel},
      {"GoToPar.Accel.Min", k.min_accel},
      {"GoToPar.Accel.Def", k.default_accel},
  };
  const auto it = values.find(rest);
  if (it == values.end()) throw CommandFailure(error::kBadProperty, name + " is not a property of this CMM");
  return ipp::Argument::call(name, {ipp::Argument::num(it->second)});
}

void IppSession::getProp(const ipp::Command& c, Responder& out) {
  if (c.args.empty()) throw CommandFailure(error::kIncorrectArguments, c.name + " needs at least one property");
  std::vector<ipp::Argument> items;
  for (const ipp::Argument& property : c.args) items.push_back(propertyValue(property));
  out.data(std::move(items));
}

void IppSession::setProp(const ipp::Command& c, Responder& out) {
  if (c.args.empty()) throw CommandFailure(error::kIncorrectArguments, "SetProp needs at least one property");
  for (const ipp::Argument& a : c.args) {
    if (!isNumberCall(a)) throw CommandFailure(error::kIncorrectArguments, "SetProp takes Property(value) items");
    const std::string& name = a.text;
    const double value = a.args[0].number;
    const bool speed = name == "Tool.GoToPar.Speed" || name == "Tool.GoToPar.Speed.Act";
    const bool accel = name == "Tool.GoToPar.Accel" || name == "Tool.GoToPar.Accel.Act";
    if (!speed && !accel) {
      throw CommandFailure(error::kBadProperty, name + " cannot be set (only the Act values of GoToPar, 6.3.6)");
    }
    // §6.3.6: outside Min..Max the value is clamped, with warning 0504.
    if (!(speed ? machine_.setSpeed(value) : machine_.setAccel(value))) {
      const double taken = speed ? machine_.speed() : machine_.accel();
      out.error(error::kArgumentOutOfRange,
                name + "(" + ipp::formatNumber(value) + ") is out of range; " + ipp::formatNumber(taken) + " taken");
    }
  }
}

// --- Tools (§6.3.2.14-19, §6.3.2.23) -----------------------------------------------------------------

void IppSession::changeTool(const ipp::Command& c, Responder&) {
  const std::string& tool = stringArgument(c);
  if (!machine_.hasTool(tool)) throw CommandFailure(error::kToolNotFound, "no tool \"" + tool + "\"; EnumTools() lists them");
  {
    std::lock_guard lock(mutex_);
    user_enabled_ = false;
  }
  if (tool == machine_.activeToolName()) return;
  const auto seconds_to_change = std::chrono::duration<double>(machine_.config().tool_change_seconds);
  if (!pause(Clock::now() + std::chrono::duration_cast<Clock::duration>(seconds_to_change))) {
    throw CommandFailure(error::kTransactionAborted, "AbortE stopped ChangeTool; the tool is still " + machine_.activeToolName());
  }
  machine_.setActiveTool(tool);
}

void IppSession::setTool(const ipp::Command& c, Responder&) {
  const std::string& tool = stringArgument(c);
  if (!machine_.hasTool(tool)) throw CommandFailure(error::kToolNotFound, "no tool \"" + tool + "\"");
  if (tool != machine_.activeToolName()) machine_.setActiveTool(tool);
}

void IppSession::findTool(const ipp::Command& c, Responder&) {
  const std::string& tool = stringArgument(c);
  const bool known = machine_.hasTool(tool);
  {
    std::lock_guard lock(mutex_);
    found_tool_ = known ? tool : "UnDefTool";  // §6.3.2.16
  }
  if (!known) throw CommandFailure(error::kToolNotFound, "no tool \"" + tool + "\"");
}

void IppSession::enumTools(const ipp::Command& c, Responder& out) {
  requireNoArguments(c);
  for (const std::string& tool : machine_.config().tools) out.data({ipp::Argument::str(tool)});
}

void IppSession::userCommand(const ipp::Command& c, Responder& out) {
  requireNoArguments(c);
  std::unique_lock lock(mutex_);
  if (c.name == "EnableUser") {
    user_enabled_ = true;
  } else if (c.name == "DisableUser") {
    user_enabled_ = false;
  } else {
    const bool enabled = user_enabled_;
    lock.unlock();
    out.data({flag("IsUserEnabled", enabled)});
  }
}

void IppSession::simpleQuery(const ipp::Command& c, Responder& out) {
  requireNoArguments(c);
  if (c.name == "IsHomed") {
    out.data({flag("IsHomed", machine_.homed())});
  } else if (c.name == "GetMachineClass") {
    out.data({ipp::Argument::call("GetMachineClass", {ipp::Argument::name(machine_.config().machine_class)})});
  } else {
    out.data({ipp::Argument::call("DMEVersion", {ipp::Argument::str("1.4.3")})});
  }
}

}  // namespace stampscan::sim::detail
