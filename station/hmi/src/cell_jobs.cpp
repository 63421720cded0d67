#include "stampscan/hmi/cell_jobs.hpp"

#include "json_views.hpp"
#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/registration/calibration_store.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>

namespace stampscan::hmi {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json progressJson(const acquisition::ScanProgress& p) {
  return {{"step", p.step},         {"steps", p.steps},     {"doing", p.doing},
          {"elapsed_s", p.elapsed_s}, {"remaining_s", p.remaining_s}, {"profiles", p.profiles},
          {"lost_profiles", p.lost_profiles}, {"positions", p.positions}};
}

// Turns what a job reports into hub events. Progress comes many times a second; the browsers get
// at most ten a second (the last one of a burst is never lost: the next event or the end carries on).
class HubObserver final : public jobs::ScanJobObserver {
 public:
  HubObserver(EventHub& hub, acquisition::Cell& cell, std::string kind,
              std::function<void(const std::string&)> on_run_folder = {}, std::function<void()> on_scan_done = {},
              LiveCloud* live_cloud = nullptr)
      : hub_(hub), cell_(cell), kind_(std::move(kind)), on_run_folder_(std::move(on_run_folder)),
        on_scan_done_(std::move(on_scan_done)), live_cloud_(live_cloud) {}

  void runFolder(const fs::path& dir) override {
    run_id_ = dir.filename().string();
    if (on_run_folder_) on_run_folder_(run_id_);
    hub_.publish("run", json{{"kind", kind_}, {"run_id", dir.filename().string()}}.dump());
  }
  void checkPassed(const std::string& what) override {
    hub_.publish("check", json{{"kind", kind_}, {"text", what}}.dump());
  }
  void progress(const acquisition::ScanProgress& p) override {
    const auto now = std::chrono::steady_clock::now();
    if (p.step < p.steps && now - last_progress_ < std::chrono::milliseconds(100)) return;
    last_progress_ = now;
    json j = progressJson(p);
    j["kind"] = kind_;
    j["devices"] = devicesJson(cell_);
    hub_.publish("progress", j.dump());
  }
  void safetyEvent(acquisition::FaultKind fault, const std::string& what) override {
    hub_.publish("safety", json{{"kind", kind_}, {"text", what}, {"fault", acquisition::toString(fault)},
                                {"advice", faultAdvice(fault)}}.dump());
  }
  void scanDone(const acquisition::ScanRunResult& r) override {
    if (on_scan_done_ && r.completed) on_scan_done_();
    hub_.publish("scan_done", json{{"kind", kind_}, {"completed", r.completed}, {"abort_reason", r.abort_reason},
                                   {"sweeps", r.sweeps_done}, {"views", r.views_done}, {"profiles", r.profiles},
                                   {"wall_seconds", r.wall_seconds}}.dump());
  }
  void stageDone(std::string_view stage, const std::string& text) override {
    hub_.publish("stage", json{{"kind", kind_}, {"stage", std::string(stage)}, {"text", text}}.dump());
  }
  // A sweep's (or view's) elements as they are measured, decimated (live_cloud.hpp), to the pages.
  void elementsMeasured(std::string_view stage, const std::vector<registration::GridElement>& elements) override {
    if (!live_cloud_) return;
    const LivePoints kept = live_cloud_->add(elements);
    const auto [measured, shown] = live_cloud_->counts();
    hub_.publish("cloud", json{{"kind", kind_}, {"stage", std::string(stage)}, {"run_id", run_id_},
                               {"xyz", kept.xyz}, {"thickness", kept.thickness}, {"measured", measured},
                               {"shown", shown}}.dump());
  }

 private:
  EventHub& hub_;
  acquisition::Cell& cell_;
  std::string kind_;
  std::function<void(const std::string&)> on_run_folder_;
  std::function<void()> on_scan_done_;
  LiveCloud* live_cloud_;
  std::string run_id_;  // set before any measuring starts (the run folder comes first)
  std::chrono::steady_clock::time_point last_progress_{};
};

}  // namespace

namespace {
// The finished event's fault and its advice.
void setFault(json& done, acquisition::FaultKind kind) {
  done["fault"] = acquisition::toString(kind);
  if (std::string advice = faultAdvice(kind); !advice.empty()) done["advice"] = std::move(advice);
}
void setFault(json& done, const std::exception& error) { setFault(done, acquisition::faultKindOf(error)); }
}  // namespace

bool isPartId(const std::string& id) {
  return !id.empty() && id.front() != '.' && std::all_of(id.begin(), id.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
  });
}

const char* toString(JobOutcome::End end) {
  switch (end) {
    case JobOutcome::End::Verdict: return "verdict";
    case JobOutcome::End::Refused: return "refused";
    case JobOutcome::End::Stopped: return "stopped";
    case JobOutcome::End::Failed: return "failed";
    case JobOutcome::End::Incomplete: return "incomplete";
    case JobOutcome::End::Done: return "done";
  }
  return "unknown";
}

std::string faultAdvice(acquisition::FaultKind kind) {
  using acquisition::FaultKind;
  switch (kind) {
    case FaultKind::DoorOpen: return "Close the cell door, then press Start again.";
    case FaultKind::EStop: return "Release the emergency stop and reset the cell, then press Start again.";
    case FaultKind::LightCurtain: return "Step out of the light curtain and clear it, then press Start again.";
    case FaultKind::Interlock:
      return "The cell's safety interlock tripped: check the door, the emergency stop and the light curtain, reset "
             "the cell, then press Start again.";
    case FaultKind::NoAir: return "Check the compressed air supply (the clamp needs it), then press Start again.";
    case FaultKind::NotClamped: return "Check that the part sits flat on the fixture, then press Start again.";
    case FaultKind::StopRequested: return "The scan was stopped on request. Press Start to scan again.";
    case FaultKind::DeviceSilent:
      return "A device does not answer: check its cable and power, then press Start again; call maintenance if it "
             "persists.";
    case FaultKind::DataLost: return "Scan the part again; call maintenance if it happens again.";
    case FaultKind::Other: return "";
  }
  return "";
}

CellJobs::CellJobs(CellSetup setup, EventHub& hub) : setup_(std::move(setup)), hub_(hub) {
  if (setup_.cell == nullptr) throw std::invalid_argument("CellJobs: no cell");
}

CellJobs::~CellJobs() {
  abort("the panel is shutting down");
  if (worker_.joinable()) worker_.join();
  if (connector_.joinable()) connector_.join();
}

void CellJobs::connectDevices() {
  if (connector_.joinable()) return;
  connector_ = std::thread([this] {
    std::lock_guard cell_lock(cell_mutex_);
    acquisition::Cell& c = *setup_.cell;
    drivers::Device* devices[] = {&c.cmm(), &c.plc(), &c.digitizer(), &c.leftCamera(), &c.rightCamera()};
    for (drivers::Device* d : devices) {
      try {
        if (d->state() != drivers::DeviceState::Ready) d->connect();
      } catch (const std::exception&) {
        // The fault is recorded on the device; the cell view shows it.
      }
    }
    hub_.publish("cell", json{{"devices", devicesJson(c)}}.dump());
  });
}

std::optional<std::string> CellJobs::begin(const std::string& kind, const std::string& user, const std::string& part_id) {
  std::lock_guard lock(mutex_);
  if (status_.busy)
    return "a " + status_.kind + " is running (started by " + status_.user + " at " + status_.started_utc +
           "): wait for it to end or abort it first";
  if (worker_.joinable()) worker_.join();  // the last job has ended; its thread is done
  status_ = JobStatus{};
  status_.busy = true;
  status_.job = ++jobs_started_;
  status_.kind = kind;
  status_.user = user;
  status_.part_id = part_id;
  status_.started_utc = registration::utcNow();
  pending_abort_.reset();
  return std::nullopt;
}

class CellJobs::RunningJob {
 public:
  template <typename Job>
  RunningJob(CellJobs& jobs, Job& job) : jobs_(jobs) {
    std::lock_guard lock(jobs_.mutex_);
    jobs_.abort_running_ = [&job](const std::string& reason) { job.abort(reason); };
    if (jobs_.pending_abort_) job.abort(*jobs_.pending_abort_);
  }
  ~RunningJob() {
    std::lock_guard lock(jobs_.mutex_);
    jobs_.abort_running_ = nullptr;
  }
  RunningJob(const RunningJob&) = delete;
  RunningJob& operator=(const RunningJob&) = delete;

 private:
  CellJobs& jobs_;
};

std::optional<std::string> CellJobs::startScan(const ScanRequest& request, const std::string& user, std::uint64_t* job) {
  if (auto refused = begin("scan", user, request.part_id)) return refused;
  {
    std::lock_guard lock(mutex_);
    status_.by_line = request.by_line;
    if (job != nullptr) *job = status_.job;
  }
  live_cloud_.reset();
  hub_.publish("started", json{{"kind", "scan"}, {"user", user}, {"by_line", request.by_line}, {"part_id", request.part_id},
                               {"program", request.program}, {"part_program", request.part_program}}.dump());
  worker_ = std::thread(&CellJobs::runScan, this, request, user);
  return std::nullopt;
}

std::optional<std::string> CellJobs::startVerify(const std::string& user) {
  if (!setup_.verify) return std::string("this cell offers no verification");
  if (auto refused = begin("verify", user, "")) return refused;
  hub_.publish("started", json{{"kind", "verify"}, {"user", user}}.dump());
  worker_ = std::thread(&CellJobs::runVerify, this, user);
  return std::nullopt;
}

std::optional<std::string> CellJobs::startCalibrate(const std::string& sensors, bool accept, const std::string& user) {
  if (!setup_.calibrate) return std::string("this cell offers no calibration");
  if (sensors != "digitizer" && sensors != "cameras" && sensors != "all")
    return std::string("sensors must be digitizer, cameras or all, not '") + sensors + "'";
  jobs::CalibrateJobOptions options = [this] {
    std::lock_guard lock(mutex_);
    return *setup_.calibrate;
  }();
  options.digitizer = sensors != "cameras";
  options.cameras = sensors != "digitizer";
  try {
    options.plan = jobs::calibrationScenesOf(options.plan, options.digitizer, options.cameras);
  } catch (const std::exception& e) {
    return std::string(e.what());
  }
  options.accepted_by = accept ? user + " (on the panel)" : "";
  if (auto refused = begin("calibrate", user, "")) return refused;
  hub_.publish("started", json{{"kind", "calibrate"}, {"user", user}, {"sensors", sensors}}.dump());
  worker_ = std::thread(&CellJobs::runCalibrate, this, std::move(options), user);
  return std::nullopt;
}

std::optional<std::string> CellJobs::abort(const std::string& reason) {
  std::lock_guard lock(mutex_);
  if (!status_.busy) return std::string("nothing is running");
  if (status_.measuring)
    return std::string("the scan's motion is over: it is being measured and ends by itself in a few seconds");
  if (abort_running_) abort_running_(reason);
  else pending_abort_ = reason;  // before the job object exists: it takes the abort as it starts
  return std::nullopt;
}

JobStatus CellJobs::status() const {
  std::lock_guard lock(mutex_);
  return status_;
}

std::optional<JobOutcome> CellJobs::outcomeOf(std::uint64_t job) const {
  std::lock_guard lock(mutex_);
  for (const JobOutcome& outcome : outcomes_)
    if (outcome.job == job) return outcome;
  return std::nullopt;
}

acquisition::CalibrationPolicy CellJobs::calibrationPolicy() const {
  std::lock_guard lock(mutex_);
  return setup_.scan.calibration_policy;
}

void CellJobs::setCalibrationPolicy(const acquisition::CalibrationPolicy& policy) {
  std::lock_guard lock(mutex_);
  // Every job's copy of the rules: the scan's check of the calibration in use, the calibration's
  // acceptance limits, the verification's MPEs.
  setup_.scan.calibration_policy = policy;
  if (setup_.calibrate) setup_.calibrate->policy = policy;
  if (setup_.verify) {
    setup_.verify->sphere.form_mpe_mm = policy.form_mpe_mm;
    setup_.verify->sphere.size_mpe_mm = policy.size_mpe_mm;
  }
}

void CellJobs::finish(const std::string& event_json, JobOutcome outcome) {
  {
    std::lock_guard lock(mutex_);
    outcome.job = status_.job;
    outcome.kind = status_.kind;
    outcomes_.push_back(std::move(outcome));
    if (outcomes_.size() > 16) outcomes_.pop_front();
    status_ = JobStatus{};
  }
  hub_.publish("finished", event_json);
}

void CellJobs::runScan(ScanRequest request, std::string user) {
  json done = {{"kind", "scan"}, {"user", user}, {"by_line", request.by_line}, {"part_id", request.part_id}, {"ok", false}};
  JobOutcome outcome;
  try {
    std::lock_guard cell_lock(cell_mutex_);
    jobs::ScanJobOptions options = [this] {
      std::lock_guard lock(mutex_);
      return setup_.scan;
    }();
    options.part_id = request.part_id;
    options.program = request.program;
    options.material = request.material;
    options.started_by = request.by_line ? user + " (the line's PLC)" : user + " (on the panel)";
    if (request.part_program.empty() && setup_.programs.restore) setup_.programs.restore();
    if (request.part_program.empty() && options.plan.steps.empty())
      throw std::runtime_error("choose the part's program: this cell has no part of its own to scan");
    if (!request.part_program.empty()) {
      if (!setup_.programs.prepare) throw std::runtime_error("this cell offers no part programs");
      ProgramScan scan = setup_.programs.prepare(request.part_program);
      options.plan = std::move(scan.plan);
      options.part_program = scan.program;
      options.truth = std::move(scan.truth);
      if (options.material.empty()) options.material = scan.material;
      if (options.program.empty()) options.program = scan.press_program;
      options.run.session.part = options.plan.part.kind;
      options.run.session.plan = options.plan.name;
      options.run.session.grid = options.plan.part.grid;
      options.run.session.grid_pitch_mm = options.plan.part.pitch;
      options.run.session.grid_circle_diameter_mm = options.plan.part.circle_diameter;
      options.run.session.grid_line_width_mm = options.plan.part.line_width;
    }
    options.run.session.part_id = request.part_id;
    HubObserver observer(
        hub_, *setup_.cell, "scan",
        [this](const std::string& run_id) {
          live_cloud_.setRun(run_id);
          std::lock_guard lock(mutex_);
          status_.run_id = run_id;
        },
        [this] {
          std::lock_guard lock(mutex_);
          status_.measuring = true;
        },
        &live_cloud_);
    jobs::ScanJob job(*setup_.cell, &observer);
    jobs::ScanJobResult r;
    {
      const RunningJob running(*this, job);
      r = job.run(options);
    }
    done["run_id"] = r.run_dir.filename().string();
    done["elements"] = r.elements;
    done["ok"] = r.report_error.empty();
    if (r.report) {
      done["verdict"] = report::toString(r.report->verdict);
      done["verdict_reason"] = r.report->verdict_reason;
      done["max_thinning_percent"] = r.report->max_thinning_percent;
      done["min_margin_percent"] = r.report->min_margin_percent;
    }
    if (!r.report_error.empty()) done["error"] = "the scan is measured, but its report failed: " + r.report_error;
    if (r.data_loss) {
      done["data_loss"] = *r.data_loss;
      setFault(done, acquisition::FaultKind::DataLost);
    }
    if (!r.history_error.empty()) done["history_error"] = r.history_error;
    if (!r.report) {
      outcome.end = JobOutcome::End::Failed;
      outcome.error = "its report failed: " + r.report_error;
    } else if (r.data_loss) {
      outcome.end = JobOutcome::End::Incomplete;
      outcome.verdict = r.report->verdict;
      outcome.error = *r.data_loss;
    } else {
      outcome.end = JobOutcome::End::Verdict;
      outcome.verdict = r.report->verdict;
    }
  } catch (const acquisition::ScanError& e) {
    done["error"] = std::string("refused before anything moved: ") + e.what();
    setFault(done, e);
    outcome.end = JobOutcome::End::Refused;
    outcome.error = e.what();
  } catch (const std::exception& e) {
    done["error"] = e.what();
    setFault(done, e);
    outcome.end = dynamic_cast<const jobs::ScanStopped*>(&e) != nullptr ? JobOutcome::End::Stopped : JobOutcome::End::Failed;
    outcome.error = e.what();
    std::lock_guard lock(mutex_);
    if (!status_.run_id.empty()) done["run_id"] = status_.run_id;
  }
  finish(done.dump(), std::move(outcome));
}

void CellJobs::runVerify(std::string user) {
  json done = {{"kind", "verify"}, {"user", user}, {"ok", false}};
  JobOutcome outcome;
  try {
    std::lock_guard cell_lock(cell_mutex_);
    jobs::VerifyJobOptions options = [this] {
      std::lock_guard lock(mutex_);
      return *setup_.verify;
    }();
    if (const fs::path stored = setup_.calibration_dir / "digitizer.json"; fs::exists(stored))
      jobs::verifyWithCalibration(options, stored);
    HubObserver observer(hub_, *setup_.cell, "verify");
    jobs::VerifyJob job(*setup_.cell, &observer);
    jobs::VerifyJobResult r;
    {
      const RunningJob running(*this, job);
      r = job.run(options);
    }
    done["ok"] = true;
    done["record_id"] = r.record.id;
    done["verdict"] = registration::toString(r.record.verdict);
    done["checks"] = checksJson(r.record.checks);
    outcome.end = JobOutcome::End::Done;
  } catch (const std::exception& e) {
    done["error"] = e.what();
    setFault(done, e);
    outcome.error = e.what();
  }
  finish(done.dump(), std::move(outcome));
}

void CellJobs::runCalibrate(jobs::CalibrateJobOptions options, std::string user) {
  json done = {{"kind", "calibrate"}, {"user", user}, {"ok", false}};
  JobOutcome outcome;
  try {
    std::lock_guard cell_lock(cell_mutex_);
    HubObserver observer(hub_, *setup_.cell, "calibrate");
    jobs::CalibrateJob job(*setup_.cell, &observer);
    jobs::CalibrateJobResult r;
    {
      const RunningJob running(*this, job);
      r = job.run(options);
    }
    done["ok"] = true;
    json sensors = json::array();
    for (const auto* sensor : {&r.digitizer, &r.cameras}) {
      if (!*sensor) continue;
      const jobs::SensorCalibration& s = **sensor;
      sensors.push_back({{"sensor", s.record.kind},
                         {"record_id", s.record.id},
                         {"verdict", registration::toString(s.record.verdict)},
                         {"in_use", s.in_use},
                         {"checks", checksJson(s.record.checks)},
                         {"left_out", s.left_out},
                         {"drift", s.drift}});
    }
    done["sensors"] = sensors;
    outcome.end = JobOutcome::End::Done;
  } catch (const std::exception& e) {
    done["error"] = e.what();
    setFault(done, e);
    outcome.error = e.what();
  }
  finish(done.dump(), std::move(outcome));
}

}  // namespace stampscan::hmi
