#include "stampscan/hmi/line_handshake.hpp"

#include "json_views.hpp"
#include "stampscan/hmi/panel_log.hpp"

#include <nlohmann/json.hpp>

namespace stampscan::hmi {

namespace plc = drivers::plc;
using nlohmann::json;

namespace {

// The answer to the line for how its scan ended.
plc::CellAnswer answerFor(const JobOutcome& outcome) {
  plc::CellAnswer a;
  a.done = true;
  a.verdict = plc::LineVerdict::Error;
  switch (outcome.end) {
    case JobOutcome::End::Verdict:
      if (outcome.verdict) {
        a.verdict = *outcome.verdict == report::Verdict::Good       ? plc::LineVerdict::Good
                    : *outcome.verdict == report::Verdict::Marginal ? plc::LineVerdict::Marginal
                                                                     : plc::LineVerdict::Failed;
      } else {
        a.error = plc::LineError::ScanFailed;
      }
      break;
    case JobOutcome::End::Incomplete: a.error = plc::LineError::Incomplete; break;
    case JobOutcome::End::Refused: a.error = plc::LineError::NotReady; break;
    case JobOutcome::End::Stopped: a.error = plc::LineError::Aborted; break;
    case JobOutcome::End::Failed:
    case JobOutcome::End::Done: a.error = plc::LineError::ScanFailed; break;
  }
  return a;
}

std::string answerText(const plc::CellAnswer& a) {
  std::string text(plc::describe(a.verdict).name);
  if (a.error != plc::LineError::None) text += " (" + std::string(plc::describe(a.error).name) + ")";
  return text;
}

}  // namespace

LineHandshake::LineHandshake(CellJobs& jobs, EventHub& hub, LineHandshakeOptions options)
    : jobs_(jobs), hub_(hub), options_(options) {}

LineHandshake::~LineHandshake() { stop(); }

void LineHandshake::start() {
  std::lock_guard control(control_mutex_);
  if (thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stopping_ = false;
  }
  thread_ = std::thread([this] { loop(); });
}

void LineHandshake::stop() {
  std::lock_guard control(control_mutex_);
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
  thread_ = std::thread();
  // The line must not wait for a scan nobody will answer: it is stopped, and the line told so.
  std::optional<std::uint64_t> job;
  plc::CellAnswer answer;
  {
    std::lock_guard lock(mutex_);
    job = state_.job;
    if (job) {
      state_.answer = plc::CellAnswer{false, false, true, plc::LineVerdict::Error, plc::LineError::Aborted};
      state_.job.reset();
    }
    state_.answer.ready = false;
    answer = state_.answer;
  }
  if (job) jobs_.abort("the panel is stopping (the line's scan)");
  try {
    plc::ModbusPlc& device = jobs_.cell().plc();
    if (device.state() == drivers::DeviceState::Ready || device.state() == drivers::DeviceState::Busy)
      device.writeCellAnswer(answer);
  } catch (const std::exception&) {
    // The PLC is gone too: the next start reads back cell_busy and answers the line then.
  }
}

LineState LineHandshake::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

void LineHandshake::loop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    lock.unlock();
    plc::ModbusPlc& device = jobs_.cell().plc();
    const auto device_state = device.state();
    if (device_state == drivers::DeviceState::Ready || device_state == drivers::DeviceState::Busy) {
      try {
        poll(device);
      } catch (const std::exception& e) {
        std::lock_guard error_lock(mutex_);
        if (state_.error != e.what()) {
          hub_.publish("line", json{{"error", e.what()}}.dump());
          logLine(kLogWarning, std::string("the line's handshake cannot reach the PLC: ") + e.what());
        }
        state_.connected = false;
        state_.error = e.what();
      }
    }
    lock.lock();
    wake_.wait_for(lock, options_.poll_period, [this] { return stopping_; });
  }
}

void LineHandshake::poll(plc::ModbusPlc& device) {
  if (!read_back_) {
    // The PLC keeps the answer across a restart of the panel: take up the handshake where it was.
    plc::CellAnswer kept = device.readCellAnswer();
    std::lock_guard lock(mutex_);
    if (static_cast<std::uint16_t>(kept.verdict) >= plc::kLineVerdictCount ||
        static_cast<std::uint16_t>(kept.error) >= plc::kLineErrorCount)
      kept = plc::CellAnswer{};  // not an answer this station gave: start afresh
    if (kept.busy) {
      state_.answer = plc::CellAnswer{false, false, true, plc::LineVerdict::Error, plc::LineError::ScanFailed};
      note("the line's last scan ended with the panel that ran it: answered scan_failed");
    } else {
      state_.answer = kept;
    }
    read_back_ = true;
  }
  const plc::LineRequest request = device.readLineRequest();
  const bool interlock_clear = [&] {
    const auto inputs = device.lastInputs();
    return inputs && !inputs->interlockTripped();
  }();
  plc::CellAnswer answer;
  {
    std::lock_guard lock(mutex_);
    state_.connected = true;
    state_.error.clear();
    state_.request = request;
    if (state_.job) {
      if (const std::optional<JobOutcome> outcome = jobs_.outcomeOf(*state_.job)) {
        state_.answer = answerFor(*outcome);
        state_.job.reset();
        note("the line's scan ended: " + answerText(state_.answer) + (outcome->error.empty() ? "" : ": " + outcome->error));
      } else if (!request.start && !withdrawn_) {
        withdrawn_ = true;
        note("the line dropped its start request during its scan: aborting it");
        if (const auto refused = jobs_.abort("the line's PLC withdrew its start request"))
          note("the line dropped its start request, but the scan ends by itself: " + *refused);
      }
    } else if (request.start && !state_.answer.done) {
      takeRequest(request);
    } else if (!request.start && state_.answer.done) {
      state_.answer.done = false;
      note("the line took the answer (" + answerText(state_.answer) + ")");
    }
    state_.answer.ready =
        !state_.job && !state_.answer.done && !state_.answer.busy && interlock_clear && !jobs_.status().busy;
    answer = state_.answer;
  }
  const auto now = std::chrono::steady_clock::now();
  if (written_ == answer && now - last_write_ < options_.rewrite_period) return;
  device.writeCellAnswer(answer);
  written_ = answer;
  last_write_ = now;
}

// Called with mutex_ held.
void LineHandshake::takeRequest(const plc::LineRequest& request) {
  const std::string program_text = "program " + std::to_string(request.program_number);
  if (!request.part_id || !isPartId(*request.part_id))
    return refuse(plc::LineError::BadPartId,
                  program_text + ": the part id " +
                      (request.part_id ? "\"" + *request.part_id + "\" is not one (letters, digits, '-', '_', '.')"
                                       : std::string("holds a character that is not printable ASCII")));
  const CellPrograms& programs = jobs_.setup().programs;
  std::optional<std::string> name;
  try {
    if (programs.by_line_number) name = programs.by_line_number(request.program_number);
  } catch (const std::exception& e) {
    return refuse(plc::LineError::UnknownProgram, program_text + ": " + e.what());
  }
  if (!name) return refuse(plc::LineError::UnknownProgram, "no part program has line number " + std::to_string(request.program_number));
  ScanRequest scan;
  scan.part_id = *request.part_id;
  scan.part_program = *name;
  scan.by_line = true;
  std::uint64_t job = 0;
  if (const auto refused = jobs_.startScan(scan, "line", &job)) return refuse(plc::LineError::Busy, *refused);
  state_.job = job;
  withdrawn_ = false;
  state_.answer = plc::CellAnswer{false, true, false, plc::LineVerdict::None, plc::LineError::None};
  note("the line started " + *name + " (" + program_text + ") for part " + *request.part_id);
}

// Called with mutex_ held.
void LineHandshake::refuse(plc::LineError error, const std::string& why) {
  state_.answer = plc::CellAnswer{false, false, true, plc::LineVerdict::Error, error};
  note("the line's request is refused (" + std::string(plc::describe(error).name) + "): " + why);
}

// Called with mutex_ held.
void LineHandshake::note(const std::string& what) {
  state_.last = what;
  // Into the journal too: an unattended cell's record of what the line asked and got.
  const bool trouble = state_.answer.verdict == plc::LineVerdict::Error && state_.answer.done;
  logLine(trouble ? kLogWarning : kLogNotice, what);
  hub_.publish("line", json{{"text", what}, {"answer", lineAnswerJson(state_.answer)}}.dump());
}

}  // namespace stampscan::hmi
