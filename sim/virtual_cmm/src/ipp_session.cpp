// The virtual CMM's per-connection I++ DME server: line intake, the fast and normal queues, AbortE,
// the error state and the move report daemon. The commands themselves are in session_commands.cpp.
#include "ipp_session.hpp"

#include "stampscan/drivers/cmm/ipp_errors.hpp"

#include <algorithm>
#include <string_view>

namespace stampscan::sim::detail {

namespace error = ipp::error;
using namespace std::chrono_literals;

namespace {
constexpr auto kMinReportGap = 100ms;      // §6.3.2.7: at most 10 reports a second
constexpr auto kDistancePollStep = 20ms;   // how often a Dis(d) daemon looks at the distance moved
constexpr std::size_t kMaxQueued = 64;    // commands acknowledged but not yet started
constexpr const char* kLineMethod = "CommandLine";  // F3 for errors found before a command was known
constexpr const char* kDeviceTimeItem = "SS.Time";   // our extension of §9.1 (PROTOCOL.md)
// The particulars kept for GetErrorInfo: enough to name the culprit. A detail may quote a client's
// line of up to 64 KiB, and the answer must stay within the line limit of §6.2 (kMaxLineLength).
constexpr std::size_t kMaxErrorDetail = 1000;

std::string shortened(std::string text, std::size_t limit) {
  if (text.size() <= limit) return text;
  text.resize(limit - 3);
  return text + "...";
}

// What OnMoveReportE can report (§6.3.2.7): the six axes (§6.3.8 for the head's) and our clock.
bool isReportItem(const ipp::Argument& a) {
  if (a.kind != ipp::Argument::Kind::Call || !a.args.empty()) return false;
  return a.text == kDeviceTimeItem ||
         std::find(kAxisNames.begin(), kAxisNames.end(), std::string_view(a.text)) != kAxisNames.end();
}

// §6.2.5: in the error state only these are served (AbortE and GetErrStatusE on the fast queue).
bool allowedInErrorState(const std::string& name) {
  return name == "ClearAllErrors" || name == "GetErrorInfo" || name == "GetXtdErrStatus" || name == "EndSession" ||
         name == "StopDaemon" || name == "StopAllDaemons" || name == "GetErrStatusE" || name == "StartSession";
}
}  // namespace

void FaultInjection::failNext(int number, std::optional<int> severity) {
  std::lock_guard lock(mutex_);
  next_ = Failure{number, severity};
}

std::optional<FaultInjection::Failure> FaultInjection::take() {
  std::lock_guard lock(mutex_);
  std::optional<Failure> taken = next_;
  next_.reset();
  return taken;
}

void IppSession::Responder::data(std::vector<ipp::Argument> items) {
  session_.send(ipp::Reply::dataLine(tag_, std::move(items)));
}

void IppSession::Responder::error(int number, const std::string& detail, std::optional<int> severity) {
  ipp::ErrorReport report = ipp::makeError(number, method_);
  if (severity) report.severity = *severity;
  {
    std::lock_guard lock(session_.mutex_);
    session_.recordError(report, detail);
  }
  session_.send(ipp::Reply::errorLine(tag_, std::move(report)));
}

void IppSession::Responder::complete() { session_.send(ipp::Reply::complete(tag_)); }

IppSession::IppSession(CmmMachine& machine, FaultInjection& faults, Sink sink)
    : machine_(machine), faults_(faults), sink_(std::move(sink)) {
  executor_ = std::thread([this] { executorLoop(); });
}

IppSession::~IppSession() {
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
    work_.notify_all();
    motion_.notify_all();
    idle_.notify_all();
  }
  executor_.join();
}

bool IppSession::sessionActive() const {
  std::lock_guard lock(mutex_);
  return session_active_;
}

bool IppSession::errorState() const {
  std::lock_guard lock(mutex_);
  return error_state_;
}

std::optional<Clock::time_point> IppSession::idleSince() const {
  std::lock_guard lock(mutex_);
  if (executing_ || !queue_.empty()) return std::nullopt;
  return last_done_;
}

void IppSession::send(const ipp::Reply& reply) {
  std::string line;
  try {
    line = ipp::formatReply(reply);
  } catch (const std::invalid_argument& e) {  // a server bug, but the client must still hear something
    line = ipp::formatReply(ipp::Reply::errorLine(reply.tag, ipp::makeError(error::kErrorProcessingMethod, kLineMethod)));
  }
  if (line.size() > ipp::kMaxLineLength) {
    // §6.2 limits every line, ours too: a data response that would be longer (a Get naming one axis
    // thousands of times) is answered with an error instead.
    const ipp::ErrorReport report = ipp::makeError(error::kErrorProcessingMethod, kLineMethod);
    {
      std::lock_guard lock(mutex_);
      recordError(report, "the response would be " + std::to_string(line.size()) + " characters, over the limit of " +
                              std::to_string(ipp::kMaxLineLength) + " (6.2)");
    }
    line = ipp::formatReply(ipp::Reply::errorLine(reply.tag, report));
  }
  sink_(line);
}

void IppSession::recordError(const ipp::ErrorReport& report, const std::string& detail) {
  errors_.push_back(report);
  error_info_[report.number] = shortened(ipp::sanitizeText(detail), kMaxErrorDetail);
  if (!ipp::needsClearAllErrors(report.severity)) return;
  // §6.2.5: class 2 and above abort all pending transactions.
  error_state_ = true;
  for (Pending& pending : queue_) pending.aborted = true;
}

// --- Reader thread -------------------------------------------------------------------------------

void IppSession::onLine(const ipp::LineFramer::Line& line) {
  try {
    if (line.problem != ipp::LineFramer::Problem::None) {
      std::optional<ipp::Tag> tag;
      try {
        tag = ipp::parseTag(std::string_view(line.text).substr(0, 5));
        if (tag->isServerEvent()) tag.reset();
      } catch (const ipp::ProtocolError&) {
      }
      if (line.problem == ipp::LineFramer::Problem::MissingCr) {
        // §6.1.1: CR and LF always come as a pair; a lone LF is an illegal character.
        throw ipp::ProtocolError(error::kIllegalCharacter, line.text.size() + 1, "LF without CR ends the line",
                                 line.text, tag);
      }
      throw ipp::ProtocolError(error::kProtocolError, ipp::kMaxLineLength,
                               "line longer than " + std::to_string(ipp::kMaxLineLength) + " characters (6.2)",
                               line.text, tag);
    }
    onCommand(ipp::parseCommand(line.text));
  } catch (const ipp::ProtocolError& e) {
    replyToBadLine(e);
  }
}

void IppSession::replyToBadLine(const ipp::ProtocolError& e) {
  if (!e.tag()) {
    // §6.2.1: without a readable tag the error goes out on E0000.
    Responder(*this, ipp::Tag::serverEvent(), kLineMethod).error(e.errorNumber(), e.what());
    return;
  }
  const ipp::Tag tag = *e.tag();
  if (tagInUse(tag)) {
    Responder(*this, ipp::Tag::serverEvent(), kLineMethod)
        .error(error::kIllegalTag, "tag " + tag.str() + " is already in use by a running transaction or daemon");
    return;
  }
  if (tag.isEvent()) {  // the fast queue answers at once
    Responder out(*this, tag, kLineMethod);
    send(ipp::Reply::ack(tag));
    out.error(e.errorNumber(), e.what());
    out.complete();
    return;
  }
  enqueue({tag, std::nullopt, Pending::SyntaxError{e.errorNumber(), e.what()}, false});
}

bool IppSession::tagInUse(ipp::Tag tag) const {
  std::lock_guard lock(mutex_);
  return in_flight_.count(tag) != 0 || (daemon_ && daemon_->tag == tag);
}

void IppSession::onCommand(ipp::Command command) {
  const ipp::Tag tag = command.tag;
  if (tagInUse(tag)) {
    // §6.2.1: tags are unique while the server processes them. Answering on the tag itself would
    // corrupt the running transaction, so the error goes out on E0000.
    Responder(*this, ipp::Tag::serverEvent(), kLineMethod)
        .error(error::kIllegalTag, "tag " + tag.str() + " is already in use by a running transaction or daemon");
    return;
  }
  if (tag.isEvent()) {
    runFast(command);
    return;
  }
  enqueue({tag, std::move(command), std::nullopt, false});
}

void IppSession::enqueue(Pending pending) {
  {
    // §6.2.3: a server too busy for more delays the Ack. Not reading meanwhile pushes back on the
    // client through TCP, and the queue stays bounded.
    std::unique_lock lock(mutex_);
    idle_.wait(lock, [this] { return closing_ || queue_.size() < kMaxQueued; });
  }
  send(ipp::Reply::ack(pending.tag));  // before queueing, so that it precedes everything the executor sends
  std::lock_guard lock(mutex_);
  in_flight_.insert(pending.tag);
  queue_.push_back(std::move(pending));
  work_.notify_all();
}

bool IppSession::commandAllowed(const std::string& name, bool fast, Responder& out) {
  bool in_session = false;
  bool in_error = false;
  {
    std::lock_guard lock(mutex_);
    in_session = session_active_;
    in_error = error_state_;
  }
  if (!in_session && name != "StartSession" && name != "EndSession") {
    out.error(error::kProtocolError, "no session: send StartSession() first (6.3.1)");
    return false;
  }
  if (in_error && !allowedInErrorState(name) && !(fast && name == "AbortE")) {
    // As in the example of §6.3.1.7, but with the classes of the table of §8.2: 0511 is class 3
    // there (the example shows 2), 0514 class 2.
    out.error(error::kErrorProcessingMethod, name + " refused: the server is in the error state");
    out.error(error::kUseClearAllErrors, "send ClearAllErrors() first (6.2.5)");
    return false;
  }
  return true;
}

void IppSession::runFast(const ipp::Command& command) {
  Responder out(*this, command.tag, command.name);
  send(ipp::Reply::ack(command.tag));
  if (command.name == "AbortE") {
    abortE(command);
    return;
  }
  if (commandAllowed(command.name, true, out)) {
    try {
      if (command.name == "GetErrStatusE") {  // §6.3.2.9
        if (!command.args.empty()) throw CommandFailure(error::kIncorrectArguments, "GetErrStatusE takes no arguments");
        out.data({ipp::Argument::call("ErrStatus", {ipp::Argument::num(errorState() ? 1 : 0)})});
      } else if (command.name == "GetPropE") {  // §6.3.1.10
        getProp(command, out);
      } else if (command.name == "OnMoveReportE") {
        onMoveReportE(command, out);
      } else if (command.name.empty() || command.name.back() != 'E') {
        throw CommandFailure(error::kProtocolError,
                             "an event tag is only for fast-queue commands, whose names end in E (6.2.1)");
      } else {
        throw CommandFailure(error::kUnsupportedCommand, command.name + " is not supported");
      }
    } catch (const CommandFailure& failure) {
      out.fail(failure);
    }
  }
  out.complete();
}

// §6.3.1.5: stop the motion, answer the running command and every queued one, then AbortE's `%`;
// afterwards only ClearAllErrors is served.
void IppSession::abortE(const ipp::Command& command) {
  Responder out(*this, command.tag, command.name);
  if (!sessionActive()) {
    out.error(error::kProtocolError, "no session: send StartSession() first (6.3.1)");
    out.complete();
    return;
  }
  {
    std::unique_lock lock(mutex_);
    abort_requested_ = true;
    for (Pending& pending : queue_) pending.aborted = true;
    motion_.notify_all();
    idle_.wait(lock, [this] { return closing_ || (!executing_ && queue_.empty()); });
    abort_requested_ = false;
    error_state_ = true;
    error_info_[error::kTransactionAborted] = "AbortE() stopped the transactions in progress";
  }
  out.complete();
}

void IppSession::onMoveReportE(const ipp::Command& command, Responder& out) {
  MoveDaemon daemon;
  daemon.tag = command.tag;
  for (const ipp::Argument& a : command.args) {
    const bool number_arg = a.kind == ipp::Argument::Kind::Call && a.args.size() == 1 &&
                            a.args[0].kind == ipp::Argument::Kind::Number;
    if ((a.isCall("Time") || a.isCall("Dis")) && !number_arg) {
      throw CommandFailure(error::kIncorrectArguments, a.text + "(...) takes one number");
    }
    if (a.isCall("Time")) {
      daemon.interval = a.args[0].number;
      if (daemon.interval < 0.1) {  // §6.3.2.7: "must not be less than 0.1"
        out.error(error::kArgumentOutOfRange, "Time(" + ipp::formatNumber(daemon.interval) + ") raised to 0.1 s");
        daemon.interval = 0.1;
      }
    } else if (a.isCall("Dis")) {
      if (!(a.args[0].number > 0)) throw CommandFailure(error::kBadArgument, "Dis(d) needs d > 0");
      daemon.min_distance = a.args[0].number;
    } else if (isReportItem(a)) {
      if (std::find(daemon.items.begin(), daemon.items.end(), a.text) != daemon.items.end()) {
        throw CommandFailure(error::kIncorrectArguments, a.text + "() asked for twice (6.1.3)");
      }
      daemon.items.push_back(a.text);
    } else {
      throw CommandFailure(error::kBadProperty, "cannot report " + ipp::formatArgument(a));
    }
  }
  if (daemon.items.empty()) {
    throw CommandFailure(error::kIncorrectArguments, "nothing to report: add X(), Y(), Z(), Tool.A(), ...");
  }
  std::lock_guard lock(mutex_);
  if (daemon_) {
    throw CommandFailure(error::kDaemonAlreadyExists, "OnMoveReportE " + daemon_->tag.str() + " is still running");
  }
  daemon_ = std::move(daemon);
  motion_.notify_all();  // a move in progress starts reporting now
}

// --- Executor thread -------------------------------------------------------------------------------

void IppSession::executorLoop() {
  for (;;) {
    Pending pending;
    {
      std::unique_lock lock(mutex_);
      const auto work = [this] { return closing_ || !queue_.empty(); };
      // Between commands: the report at the last move's target, when it is due.
      while (final_report_due_ && !work()) {
        if (!work_.wait_until(lock, *final_report_due_, work)) sendFinalReport(lock);
      }
      work_.wait(lock, work);
      if (closing_) return;
      pending = std::move(queue_.front());
      queue_.pop_front();
      executing_ = true;
    }
    execute(pending);
    std::lock_guard lock(mutex_);
    executing_ = false;
    last_done_ = Clock::now();
    idle_.notify_all();
  }
}

void IppSession::execute(Pending& pending) {
  Responder out(*this, pending.tag, pending.command ? pending.command->name : kLineMethod);
  if (pending.aborted) {
    out.error(error::kTransactionAborted, "aborted before it started");
  } else if (pending.syntax_error) {
    out.error(pending.syntax_error->number, pending.syntax_error->message);
  } else if (commandAllowed(pending.command->name, false, out)) {
    try {
      if (const std::optional<FaultInjection::Failure> injected = faults_.take()) {
        const CommandFailure failure(injected->number, "injected by the test (VirtualCmm::failNextCommand)",
                                     injected->severity);
        const int severity = injected->severity.value_or(ipp::makeError(injected->number, "").severity);
        if (ipp::needsClearAllErrors(severity)) throw failure;
        out.fail(failure);  // information or a warning: the command still runs
      }
      dispatch(*pending.command, out);
    } catch (const CommandFailure& failure) {
      out.fail(failure);
    }
  }
  {
    // The tag is free again once the client sees `%`, which may be at once.
    std::lock_guard lock(mutex_);
    in_flight_.erase(pending.tag);
  }
  out.complete();
}

bool IppSession::pause(Clock::time_point until) {
  std::unique_lock lock(mutex_);
  return !motion_.wait_until(lock, until, [this] { return abort_requested_ || closing_; });
}

bool IppSession::runMove(const MachinePose& target) {
  const Clock::time_point arrival = machine_.beginMove(target, Clock::now());
  // A replayed move reports where the recorded one did.
  const std::vector<Clock::time_point> report_times = machine_.followedReportTimes();
  std::size_t next_report = 0;
  std::unique_lock lock(mutex_);
  final_report_due_.reset();  // this move's reports follow from where the last one ended
  for (;;) {
    if (report_times.empty()) break;
    const Clock::time_point now = Clock::now();
    if (abort_requested_ || closing_) {
      machine_.endMove(false, now);
      return false;
    }
    if (next_report < report_times.size() && now >= report_times[next_report]) {
      ++next_report;
      if (std::optional<std::string> report = reportNow(now)) {
        lock.unlock();
        sink_(*report);
        lock.lock();
      }
      continue;
    }
    if (now >= arrival && next_report >= report_times.size()) break;
    motion_.wait_until(lock, next_report < report_times.size() ? report_times[next_report] : arrival);
  }
  for (;;) {
    const Clock::time_point now = Clock::now();
    if (abort_requested_ || closing_) {
      machine_.endMove(false, now);  // AbortE: "stop all motion as soon as possible"
      return false;
    }
    if (now >= arrival) break;
    if (std::optional<std::string> report = dueReport(now, false)) {
      lock.unlock();
      sink_(*report);
      lock.lock();
      continue;
    }
    motion_.wait_until(lock, std::min(arrival, nextReportCheck(now)));
  }
  machine_.endMove(true, arrival);
  // One more report at the target, so the client's last report is where the move ended: now when
  // the rate limit allows, else from the executor as soon as it does (sendFinalReport()). The move
  // is complete when the machine arrives, as a machine's `%` does not wait for its daemon.
  if (daemon_ && !abort_requested_ && !closing_) {
    if (std::optional<std::string> report = dueReport(Clock::now(), true)) {
      lock.unlock();
      sink_(*report);
      lock.lock();
    } else if (daemon_->reported && daemon_->last_pose != machine_.pose(Clock::now())) {
      final_report_due_ = daemon_->last_time + kMinReportGap;
    }
  }
  return true;
}

void IppSession::sendFinalReport(std::unique_lock<std::mutex>& lock) {
  final_report_due_.reset();
  if (!daemon_ || closing_) return;
  if (std::optional<std::string> report = dueReport(Clock::now(), true)) {
    lock.unlock();
    sink_(*report);
    lock.lock();
  }
}

std::optional<std::string> IppSession::dueReport(Clock::time_point now, bool at_rest) {
  if (!daemon_) return std::nullopt;
  MoveDaemon& d = *daemon_;
  const MachinePose pose = machine_.pose(now);
  if (d.reported) {
    const auto since = now - d.last_time;
    if (since < kMinReportGap) return std::nullopt;
    bool due = false;
    if (at_rest) {
      due = pose != d.last_pose;  // a turn of the head alone ends somewhere new too
    } else if (d.interval == 0 && d.min_distance == 0) {
      due = true;  // neither Time nor Dis: as often as allowed
    } else {
      due = (d.interval > 0 && seconds(since) >= d.interval) ||
            (d.min_distance > 0 && distance(pose.xyz, d.last_pose.xyz) >= d.min_distance);  // Dis is mm
    }
    if (!due) return std::nullopt;
  }
  return reportNow(now);
}

std::optional<std::string> IppSession::reportNow(Clock::time_point now) {
  if (!daemon_) return std::nullopt;
  MoveDaemon& d = *daemon_;
  const MachinePose pose = machine_.pose(now);
  d.reported = true;
  d.last_time = now;
  d.last_pose = pose;
  std::vector<ipp::Argument> items;
  for (const std::string& item : d.items) {
    double value = 0;
    if (item == kDeviceTimeItem) {
      value = seconds(now - session_start_);
    } else {
      const auto axis = std::find(kAxisNames.begin(), kAxisNames.end(), std::string_view(item));
      value = pose.axis(static_cast<std::size_t>(axis - kAxisNames.begin()));
    }
    items.push_back(ipp::Argument::call(item, {ipp::Argument::num(value)}));
  }
  return ipp::formatReply(ipp::Reply::dataLine(d.tag, std::move(items)));
}

Clock::time_point IppSession::nextReportCheck(Clock::time_point now) const {
  if (!daemon_) return Clock::time_point::max();
  const MoveDaemon& d = *daemon_;
  if (!d.reported) return now;
  const Clock::time_point earliest = d.last_time + kMinReportGap;
  Clock::time_point next = Clock::time_point::max();
  if (d.interval > 0) {
    next = std::max(earliest, d.last_time + std::chrono::duration_cast<Clock::duration>(
                                                 std::chrono::duration<double>(d.interval)));
  }
  if (d.min_distance > 0) next = std::min(next, std::max(earliest, now + kDistancePollStep));
  if (d.interval == 0 && d.min_distance == 0) next = earliest;
  return next;
}

}  // namespace stampscan::sim::detail
