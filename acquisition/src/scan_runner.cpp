#include "stampscan/acquisition/scan_runner.hpp"

#include "stampscan/acquisition/safety_interlock.hpp"
#include "stampscan/acquisition/trace/trace_messages.hpp"
#include "stampscan/drivers/camera/stereo_pair.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <vector>

namespace stampscan::acquisition {

namespace msg = stampscan::trace;
using drivers::cmm::CmmPosition;
using drivers::cmm::MoveOutcome;
using drivers::cmm::ToolOrientation;
using drivers::plc::Coil;

namespace {

// Thrown inside run() when the run must end after motion began.
struct Aborted {
  FaultKind kind;
  std::string reason;
};

CmmPosition positionOf(const HeadPose& p) { return {p.position[0], p.position[1], p.position[2]}; }
ToolOrientation orientationOf(const HeadPose& p) { return {p.a, p.b, 0}; }

std::string describe(const PlanStep& step) {
  return std::visit([](const auto& s) {
    using T = std::decay_t<decltype(s)>;
    if constexpr (std::is_same_v<T, SweepStep>) return msg::sweepLabel(s.scene, s.index);
    else return std::string(toString(s.scene)) + " view " + std::to_string(s.index);
  }, step);
}

}  // namespace

struct ScanRunner::Impl {
  CellDevices dev;
  trace::TraceSink& sink;
  const StationClock& clock;
  ScanObserver* observer;

  std::mutex sink_mutex;  // the devices' threads write one message at a time
  std::atomic<std::uint64_t> positions{0}, profiles{0}, plc_states{0};
  std::int64_t cmm_offset = 0;  // CMM clock to station clock; the CMM driver's reader thread's alone
  std::mutex pair_mutex;  // the stereo pairs that arrived, by trigger id
  std::condition_variable pair_arrived;
  std::set<std::uint64_t> arrived_pairs;  // their trigger ids
  double camera_exposure_us = -1;          // the longer of the two cameras' exposures; < 0: unknown
  std::mutex abort_mutex;
  std::optional<std::string> abort_reason;

  Impl(CellDevices d, trace::TraceSink& s, const StationClock& c, ScanObserver* o) : dev(d), sink(s), clock(c), observer(o) {}

  void write(std::string_view topic, std::int64_t log_time, std::vector<std::byte> bytes) {
    std::lock_guard lock(sink_mutex);
    sink.message(topic, log_time, std::move(bytes));
  }

  void event(msg::CmmEventKind kind, const std::string& detail) {
    msg::CmmEvent e;
    e.station_time_ns = clock.now();
    e.kind = kind;
    e.detail = detail;
    write(msg::topics::kCmmEvent, e.station_time_ns, msg::encode(e));
  }

  void marker(Scene scene, const char* phase, std::uint32_t index) {
    msg::SceneMarker m;
    m.station_time_ns = clock.now();
    m.scene = scene;
    m.phase = phase;
    m.index = index;
    write(msg::topics::kScene, m.station_time_ns, msg::encode(m));
  }

  void position(std::int64_t t, const CmmPosition& p, const ToolOrientation& o) {
    msg::CmmPosition m;
    m.station_time_ns = t;
    m.x = p.x, m.y = p.y, m.z = p.z;
    m.head_a = o.a;
    m.head_b = o.b;
    ++positions;
    write(msg::topics::kCmmPosition, t, msg::encode(m));
  }

  // The head where it stands, read at one instant: a sample of the track at both ends of a move, so
  // that the track is exact where the head is still (move reports come only while it moves).
  void samplePose() {
    const std::int64_t before = clock.now();
    const drivers::cmm::CmmPose p = dev.cmm.pose();
    const std::int64_t after = clock.now();
    position(before + (after - before) / 2, p.position, p.orientation);
  }

  // A pair of readings of the station clock and the digitizer's, the device's between two station
  // readings: the pair's error is at most half the request's round trip, so the tightest of a few
  // brackets is kept (a loaded host or bus delays some requests by milliseconds).
  void clockSync() {
    timed(spent.clock_sync, [&] { clockSyncUntimed(); });
  }
  void clockSyncUntimed() {
    std::int64_t best_rtt = std::numeric_limits<std::int64_t>::max();
    msg::ClockSync best;
    for (int i = 0; i < 5; ++i) {
      const std::int64_t before = clock.now();
      drivers::digitizer::DeviceStatus status;
      try {
        status = dev.digitizer.readStatus();
      } catch (const drivers::DeviceError&) {
        continue;  // one bracket missing is no harm
      }
      const std::int64_t after = clock.now();
      if (after - before < best_rtt) {
        best_rtt = after - before;
        best.station_time_ns = before + (after - before) / 2;
        best.device_time_ns = static_cast<std::int64_t>(status.device_time_ns);
      }
    }
    if (best_rtt == std::numeric_limits<std::int64_t>::max()) return;
    best.device = "digitizer";
    write(msg::topics::kClockSync, best.station_time_ns, msg::encode(best));
  }

  void plcState(const drivers::plc::PlcInputs& in, const drivers::plc::PlcOutputs& out) {
    msg::PlcState s;
    s.station_time_ns = clock.now();
    s.door_closed = in.door_closed;
    s.estop_ok = in.e_stop_chain_ok;
    s.light_curtain_clear = in.light_curtain_clear;
    s.part_clamped = in.part_clamped;
    s.laser_shutter_open = !in.laser_shutter_closed;
    s.stack_light = static_cast<std::uint8_t>((out.stack_light_green ? 1 : 0) | (out.stack_light_amber ? 2 : 0) |
                                              (out.stack_light_red ? 4 : 0));
    s.heartbeat = in.plc_heartbeat;
    ++plc_states;
    write(msg::topics::kPlcState, s.station_time_ns, msg::encode(s));
  }

  // A pair of frames from the stereo pair's stream threads: both frames and both cameras' clock
  // pairs (the driver's station time of a frame is its device time plus the measured offset).
  void onStereoPair(const drivers::camera::StereoFrame& pair) {
    for (const drivers::camera::Frame* f : {&pair.left, &pair.right}) {
      const bool left = f == &pair.left;
      msg::CameraFrame m;
      m.camera = left ? "left" : "right";
      m.frame_id = f->info.frame_id;
      m.trigger_id = pair.trigger_id;
      m.device_time_ns = f->info.device_time_ns;
      m.width = f->info.width;
      m.height = f->info.height;
      m.encoding = f->info.pixel_format == "Mono16" ? "mono16" : "mono8";
      m.step = m.width * (m.encoding == "mono16" ? 2u : 1u);
      m.data = f->data;
      write(left ? msg::topics::kCameraLeft : msg::topics::kCameraRight, clock.now(), msg::encode(m));
      msg::ClockSync c;
      c.device = left ? "camera_left" : "camera_right";
      c.station_time_ns = f->info.station_time_ns;
      c.device_time_ns = f->info.device_time_ns;
      write(msg::topics::kClockSync, clock.now(), msg::encode(c));
    }
    {
      std::lock_guard lock(pair_mutex);
      arrived_pairs.insert(pair.trigger_id);
    }
    pair_arrived.notify_all();
  }

  void configureCameras(const ScanRunParams& params) {
    if (!params.session.camera_nominal)
      throw ScanError("the plan has stereo views, but the session description gives no camera image size");
    drivers::camera::CameraConfig config;
    config.pixel_format = params.session.camera_bits > 8 ? "Mono16" : "Mono8";
    config.roi = {0, 0, params.session.camera_nominal->width, params.session.camera_nominal->height};
    config.trigger = drivers::camera::TriggerMode::Software;
    camera_exposure_us = 0;
    for (drivers::camera::GigECamera* camera : {dev.left_camera, dev.right_camera}) {
      try {
        camera->configure(config);
      } catch (const std::exception& e) {
        throw ScanError(camera->name() + " refuses the scan's image format: " + e.what());
      }
      const std::optional<double> exposure = camera->readConfig().exposure_us;
      camera_exposure_us = exposure && camera_exposure_us >= 0 ? std::max(camera_exposure_us, *exposure) : -1;
    }
  }

  std::optional<std::string> abortReason() {
    std::lock_guard lock(abort_mutex);
    return abort_reason;
  }

  // ---- Checks before motion --------------------------------------------------------------------

  void connect(drivers::Device& device, const char* what) {
    try {
      if (device.state() != drivers::DeviceState::Ready) device.connect();
    } catch (const std::exception& e) {
      throw ScanError(std::string(what) + " does not answer: " + e.what() + " (run `station devices` to see the cell)",
                      FaultKind::DeviceSilent);
    }
    if (observer) observer->checkPassed(std::string(what) + " answers: " + device.identity().model);
  }

  void checkInterlocks(const ScanRunParams& params) {
    drivers::plc::PlcInputs in;
    try {
      in = dev.plc.readInputs();
    } catch (const std::exception& e) {
      throw ScanError(std::string("the PLC does not answer: ") + e.what(), FaultKind::DeviceSilent);
    }
    if (!in.door_closed) throw ScanError("the cell door is open: close it and start again", FaultKind::DoorOpen);
    if (!in.e_stop_chain_ok)
      throw ScanError("the e-stop chain is broken: release the e-stop, reset the cell and start again", FaultKind::EStop);
    if (!in.light_curtain_clear)
      throw ScanError("the light curtain is interrupted: clear it and start again", FaultKind::LightCurtain);
    if (!in.air_pressure_ok) throw ScanError("no air pressure: open the air supply and start again", FaultKind::NoAir);
    if (observer) observer->checkPassed("interlocks healthy: door closed, e-stop chain, light curtain, air");
    // Clear a tripped interlock (no automatic restart: the station writes the coils again), ask for
    // the clamp and motion.
    drivers::plc::PlcOutputs out;
    out.stack_light_amber = true;
    out.clamp_request = true;
    out.motion_enable = true;
    dev.plc.writeOutputs(out);
    const auto deadline = std::chrono::steady_clock::now() + params.clamp_timeout;
    while (!dev.plc.readInputs().part_clamped) {
      if (std::chrono::steady_clock::now() > deadline)
        throw ScanError("the part is not clamped " + std::to_string(params.clamp_timeout.count()) +
                        " ms after the clamp was asked for: check the part and the clamp",
                      FaultKind::NotClamped);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (observer) observer->checkPassed("part clamped");
  }

  // ---- Motion ----------------------------------------------------------------------------------

  void checkAbort(SafetyInterlock& safety) {
    if (auto reason = abortReason()) throw Aborted{FaultKind::StopRequested, *reason};
    if (safety.tripped()) {
      const auto events = safety.events();
      // The first event is the cause; the interlock's own trip follows it.
      if (events.empty()) throw Aborted{FaultKind::Interlock, "safety interlock"};
      throw Aborted{events.front().kind, events.front().what};
    }
  }

  // Adds the time `f` takes to `slot` (ScanRunResult::TimeSpent).
  template <typename F>
  static void timed(double& slot, F&& f) {
    const auto t0 = std::chrono::steady_clock::now();
    struct Add {
      double& slot;
      std::chrono::steady_clock::time_point t0;
      ~Add() { slot += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); }
    } add{slot, t0};
    f();
  }
  ScanRunResult::TimeSpent spent;

  void move(SafetyInterlock& safety, const HeadPose& target, double speed) {
    timed(spent.moving, [&] { moveUntimed(safety, target, speed); });
  }
  void moveUntimed(SafetyInterlock& safety, const HeadPose& target, double speed) {
    checkAbort(safety);
    MoveOutcome outcome;
    try {
      outcome = dev.cmm.goTo(positionOf(target), orientationOf(target), speed);
    } catch (const drivers::DeviceError& e) {
      checkAbort(safety);  // an abort mid-move may surface as an error
      // One retry after clearing the CMM's errors (I++ DME ClearAllErrors); then the run ends.
      try {
        dev.cmm.clearAllErrors();
        outcome = dev.cmm.goTo(positionOf(target), orientationOf(target), speed);
      } catch (const std::exception& again) {
        throw Aborted{faultKindOf(again), std::string("the CMM refused a move twice: ") + again.what()};
      }
    }
    if (outcome == MoveOutcome::Aborted) {
      checkAbort(safety);
      throw Aborted{FaultKind::Other, "the CMM stopped the move"};
    }
  }

  void shutter(bool open) { dev.plc.setOutput(Coil::LaserShutterOpenRequest, open); }

  // ---- The run, phase by phase ----------------------------------------------------------------

  // What one run carries from phase to phase.
  struct Running {
    const ScanPlan& plan;
    const ScanRunParams& params;
    const drivers::digitizer::ConfigReply& config;
    SafetyInterlock& safety;
    ScanRunResult& result;
    std::unique_ptr<drivers::camera::StereoPair> pair = nullptr;
    // How long the head stays after a trigger when it need not wait for the frames (leaveAfter()).
    std::optional<std::chrono::microseconds> leave_after{};
    // Views the head has left whose frames are still on their way.
    struct OutstandingView {
      std::uint64_t trigger = 0;
      std::size_t step = 0;
      std::chrono::steady_clock::time_point triggered;
    };
    std::vector<OutstandingView> outstanding{};
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
    std::uint64_t lost_before = 0;  // the digitizer's lost profiles before the run
    double motion_done = 0;         // s of the plan's motion done, for the time left
    HeadPose at = {};               // where the head was sent last
    double elapsed() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
  };

  ScanRunResult run(const ScanPlan& plan, const ScanRunParams& params) {
    checkRunnable(plan, params);
    // An abort that came before the run (an operator pressing Abort as the job starts) is kept: it
    // ends the run at its first step. A runner plays one plan.
    const bool stereo = plan.stereoCount() > 0;
    ScanRunResult result;
    result.devices = connectDevices(params, stereo);
    if (params.before_motion) params.before_motion(result.devices);
    checkInterlocks(params);
    result.motion_seconds = motionSeconds(plan, params.limits);
    const drivers::digitizer::ConfigReply config = dev.digitizer.readConfig();
    recordSession(plan, params, config);

    SafetyInterlock safety(dev.plc, dev.cmm);
    Running r{plan, params, config, safety, result};
    r.lost_before = dev.digitizer.counters().lost_profiles;
    r.at = plan.park;
    std::optional<PlcStatePoller> poller;
    poller.emplace(*this, params.plc_state_period);
    try {
      startCmmReports(params);
      if (stereo) {
        r.pair = startStereoPair();
        r.leave_after = leaveAfter();
      }
      home(r);
      runSteps(r);
      park(r);
      result.completed = true;
      dev.plc.setOutput(Coil::ClampRequest, false);
    } catch (const Aborted& a) {
      result.abort_reason = a.reason;
      result.abort_kind = a.kind;
    } catch (const std::exception& e) {
      result.abort_reason = e.what();
      result.abort_kind = faultKindOf(e);
    }
    if (!result.completed) endEarly(result.abort_reason);
    if (r.pair) r.pair->stop();
    try {
      dev.cmm.stopMoveReports();
    } catch (const std::exception&) {
    }
    poller.reset();
    for (const SafetyEvent& e : safety.events()) {
      result.safety_events.push_back(e.what);
      if (observer) observer->safetyEvent(e.kind, e.what);
    }
    result.wall_seconds = r.elapsed();
    result.spent = spent;
    result.spent.other = result.wall_seconds - spent.moving - spent.settling - spent.frames - spent.clock_sync -
                         spent.digitizer;
    result.profiles = profiles;
    result.positions = positions;
    result.plc_states = plc_states;
    result.lost_profiles = dev.digitizer.counters().lost_profiles - r.lost_before;
    return result;
  }

  // A plan outside the machine, or with views and no cameras, is refused before anything moves.
  void checkRunnable(const ScanPlan& plan, const ScanRunParams& params) const {
    const std::vector<std::string> problems = checkPlan(plan, params.limits);
    if (!problems.empty()) {
      std::string text = "the plan cannot run on this cell: " + problems.front();
      if (problems.size() > 1) text += " (and " + std::to_string(problems.size() - 1) + " more)";
      throw ScanError(text);
    }
    if (plan.stereoCount() > 0 && (!dev.left_camera || !dev.right_camera))
      throw ScanError("the plan has " + std::to_string(plan.stereoCount()) + " stereo views, but the cell has no cameras");
  }

  std::vector<drivers::DeviceIdentity> connectDevices(const ScanRunParams& params, bool stereo) {
    connect(dev.cmm, "the CMM");
    connect(dev.plc, "the PLC");
    connect(dev.digitizer, "the digitizer");
    if (stereo) {
      connect(*dev.left_camera, "the left camera");
      connect(*dev.right_camera, "the right camera");
      configureCameras(params);
    }
    std::vector<drivers::DeviceIdentity> devices{dev.cmm.identity(), dev.plc.identity(), dev.digitizer.identity()};
    if (stereo) {
      devices.push_back(dev.left_camera->identity());
      devices.push_back(dev.right_camera->identity());
    }
    return devices;
  }

  // The session description, with what the devices say of themselves, as the trace's metadata.
  void recordSession(const ScanPlan& plan, const ScanRunParams& params, const drivers::digitizer::ConfigReply& config) {
    trace::SessionDescription session = params.session;
    session.part = plan.part.kind;
    session.plan = plan.name;
    session.plan_toml = toToml(plan);
    session.grid = plan.part.grid;
    session.grid_pitch_mm = plan.part.pitch;
    session.grid_circle_diameter_mm = plan.part.circle_diameter;
    session.grid_line_width_mm = plan.part.line_width;
    session.digitizer_points_per_profile = config.config.points_per_profile;
    session.digitizer_profile_rate_hz = config.config.profile_rate_hz;
    session.station_clock = trace::kStationClockText;
    std::lock_guard lock(sink_mutex);
    sink.metadata(std::string(trace::kSessionMetadataName), trace::encodeSession(session));
  }

  // The PLC's state into the trace at a steady rate (the driver's watchdog thread reads it), from
  // construction until destruction: every way out of run(), an exception included.
  class PlcStatePoller {
   public:
    PlcStatePoller(Impl& impl, std::chrono::milliseconds period)
        : thread_([this, &impl, period] {
            while (!stop_) {
              if (const auto in = impl.dev.plc.lastInputs()) {
                try {
                  impl.plcState(*in, impl.dev.plc.readOutputs());
                } catch (const std::exception&) {
                }
              }
              std::this_thread::sleep_for(period);
            }
          }) {}
    ~PlcStatePoller() {
      stop_ = true;
      thread_.join();
    }
    PlcStatePoller(const PlcStatePoller&) = delete;
    PlcStatePoller& operator=(const PlcStatePoller&) = delete;

   private:
    std::atomic<bool> stop_{false};
    std::thread thread_;
  };

  // A report's position was sampled by the CMM some time before the line arrived, and how long
  // before varies with the load on both sides (a millisecond is 25 um along a sweep at 25 mm/s).
  // When the CMM stamps its reports with its own clock, that stamp is put on the station clock by
  // the smallest arrival delay seen so far: the delay's floor, which the jitter only adds to.
  void startCmmReports(const ScanRunParams& params) {
    cmm_offset = std::numeric_limits<std::int64_t>::max();
    dev.cmm.startMoveReports(params.report_interval_s, [this](const drivers::cmm::MoveReport& r) {
      std::int64_t t = clock.fromSteady(r.arrival_steady_ns);
      if (r.device_time_s) {
        const auto device_ns = static_cast<std::int64_t>(std::llround(*r.device_time_s * 1e9));
        cmm_offset = std::min(cmm_offset, t - device_ns);
        t = device_ns + cmm_offset;
      }
      position(t, r.position, r.orientation.value_or(ToolOrientation{}));
    }, drivers::cmm::MoveReportContent::PositionAndOrientation);
  }

  // The trigger id pairs the frames; the head stands still through a view, so how far apart the two
  // exposures are stamped does not move the geometry. A wide tolerance keeps cameras whose clock
  // offsets are only estimated from frame arrivals (no timestamp latch) paired.
  std::unique_ptr<drivers::camera::StereoPair> startStereoPair() {
    drivers::camera::StereoPairOptions pairing;
    pairing.tolerance = std::chrono::seconds(1);
    auto pair = std::make_unique<drivers::camera::StereoPair>(
        *dev.left_camera, *dev.right_camera, [this](const drivers::camera::StereoFrame& f) { onStereoPair(f); }, pairing);
    pair->start();
    return pair;
  }

  void report(const Running& r, std::size_t step, const std::string& doing) {
    if (!observer) return;
    ScanProgress p;
    p.step = step;
    p.steps = r.plan.steps.size();
    p.doing = doing;
    p.elapsed_s = r.elapsed();
    p.remaining_s = std::max(0.0, r.result.motion_seconds - r.motion_done);
    p.profiles = profiles;
    p.lost_profiles = dev.digitizer.counters().lost_profiles - r.lost_before;
    p.positions = positions;
    observer->progress(p);
  }

  void home(Running& r) {
    if (!dev.cmm.isHomed()) {
      report(r, 0, "homing");
      event(msg::CmmEventKind::MoveBegin, "home");
      if (dev.cmm.home() == MoveOutcome::Aborted) checkAbort(r.safety);
      event(msg::CmmEventKind::MoveEnd, "home");
    }
    samplePose();
    clockSync();
  }

  // Each step between the markers of its scene: a scene begins at its first step and ends after its
  // last one of a run of steps.
  void runSteps(Running& r) {
    const auto sceneOf = [&](std::size_t k) {
      return k < r.plan.steps.size() ? std::optional<Scene>(std::visit([](const auto& s) { return s.scene; }, r.plan.steps[k]))
                                     : std::nullopt;
    };
    for (std::size_t k = 0; k < r.plan.steps.size(); ++k) {
      const Scene scene = *sceneOf(k);
      const bool first = k == 0 || sceneOf(k - 1) != scene, last = sceneOf(k + 1) != scene;
      if (const auto* view = std::get_if<StereoStep>(&r.plan.steps[k])) {
        runView(r, k, *view, first, last);
      } else {
        runSweep(r, k, std::get<SweepStep>(r.plan.steps[k]), first, last);
        ++r.result.sweeps_done;
      }
      ++r.result.steps_done;
    }
  }

  void travelTo(Running& r, std::size_t k, const HeadPose& target) {
    report(r, k, "travel to " + describe(r.plan.steps[k]));
    event(msg::CmmEventKind::MoveBegin, "travel");
    move(r.safety, target, r.plan.travel_speed);
    event(msg::CmmEventKind::MoveEnd, "travel");
    samplePose();
    r.motion_done += moveSeconds(r.at, target, r.plan.travel_speed, r.params.limits);
    r.at = target;
  }

  // The head may leave a view as soon as both exposures are over when both cameras stamp their
  // frames on a clock the station reads to the millisecond (a latched timestamp): the frames, still
  // on their way, say when they were exposed, and the head's track says where it stood then. A
  // camera whose clock is only estimated from its frames' arrivals, or whose exposure time is not
  // known, keeps the head until the frames are in.
  std::optional<std::chrono::microseconds> leaveAfter() const {
    for (const drivers::camera::GigECamera* camera : {dev.left_camera, dev.right_camera})
      if (camera->clockSyncMethod() != drivers::camera::ClockSyncMethod::TimestampLatch) return std::nullopt;
    if (camera_exposure_us < 0) return std::nullopt;
    // The trigger is acknowledged once the cameras have it; a millisecond more for their trigger
    // latency and the clock's bracket.
    return std::chrono::microseconds(static_cast<std::int64_t>(std::ceil(camera_exposure_us))) + std::chrono::milliseconds(1);
  }

  // Settle, trigger both cameras, and stay for the exposure (leaveAfter()) or for the frames. A view
  // without frames is marked missing and the scan goes on. The scene's end marker comes after all
  // its frames.
  void runView(Running& r, std::size_t k, const StereoStep& view, bool first, bool last) {
    travelTo(r, k, view.pose);
    r.motion_done += view.settle_s;
    if (first) marker(view.scene, "begin", view.index);
    report(r, k, describe(r.plan.steps[k]));
    timed(spent.settling, [&] { std::this_thread::sleep_for(std::chrono::duration<double>(view.settle_s)); });
    checkAbort(r.safety);
    timed(spent.frames, [&] {
      std::optional<std::uint64_t> id;
      try {
        id = r.pair->trigger();
      } catch (const drivers::DeviceError& e) {
        if (observer) observer->safetyEvent(faultKindOf(e), std::string("camera: ") + e.what());
      }
      if (!id) {
        viewMissing(r, k);
        return;
      }
      r.outstanding.push_back({*id, k, std::chrono::steady_clock::now()});
      if (r.leave_after) {
        std::this_thread::sleep_for(*r.leave_after);
      } else {
        collectViews(r);
      }
    });
    if (last) {
      timed(spent.frames, [&] { collectViews(r); });
      marker(view.scene, "end", view.index);
    }
  }

  // Waits for the frames of every view the head has left, each until its trigger's frame timeout.
  void collectViews(Running& r) {
    for (const Running::OutstandingView& v : r.outstanding) {
      std::unique_lock lock(pair_mutex);
      const bool arrived = pair_arrived.wait_until(lock, v.triggered + r.params.frame_timeout,
                                                   [&] { return arrived_pairs.contains(v.trigger); });
      lock.unlock();
      if (arrived) {
        ++r.result.views_done;
      } else {
        viewMissing(r, v.step);
      }
    }
    r.outstanding.clear();
  }

  void viewMissing(Running& r, std::size_t k) {
    ++r.result.views_missing;
    event(msg::CmmEventKind::ViewMissing, describe(r.plan.steps[k]));
  }

  // A sweep that lost more profiles on the way than the limit is run again, once; the trace says the
  // first run is not to be used ("sweep_discarded").
  void runSweep(Running& r, std::size_t k, const SweepStep& sweep, bool first, bool last) {
    if (first) marker(sweep.scene, "begin", sweep.index);
    const std::string label = msg::sweepLabel(sweep.scene, sweep.index);
    for (int attempt = 0;; ++attempt) {
      const std::uint64_t lost = sweepOnce(r, k, sweep, label);
      if (lost <= r.params.max_lost_profiles_per_sweep) break;
      if (attempt > 0) {
        // Repeated once and still over the limit: kept, and the loss is reported with the result.
        ++r.result.sweeps_over_loss_limit;
        if (observer) observer->safetyEvent(FaultKind::DataLost, label + ": " + std::to_string(lost) + " profiles lost again; kept");
        break;
      }
      event(msg::CmmEventKind::SweepDiscarded, label);
      if (observer) observer->safetyEvent(FaultKind::DataLost, label + ": " + std::to_string(lost) + " profiles lost; sweeping again");
      ++r.result.sweeps_repeated;
    }
    if (last) {
      timed(spent.frames, [&] { collectViews(r); });  // a scene's views before its end
      marker(sweep.scene, "end", sweep.index);
    }
  }

  // One run of a sweep: to its start, the laser on, along it at its speed, the profiles drained, the
  // laser off. Returns the profiles it lost.
  std::uint64_t sweepOnce(Running& r, std::size_t k, const SweepStep& sweep, const std::string& label) {
    travelTo(r, k, sweep.start);
    clockSync();
    const std::uint64_t lost_at_start = dev.digitizer.counters().lost_profiles;
    shutter(true);
    timed(spent.digitizer, [&] { startDigitizer(r.config); });
    report(r, k, describe(r.plan.steps[k]));
    event(msg::CmmEventKind::SweepBegin, label);
    try {
      move(r.safety, sweep.end, sweep.speed);
    } catch (...) {
      // The shutter first: stop() now waits for the profiles the head made, which a loaded host
      // may take seconds to collect, and an interrupted sweep must not keep the laser open.
      shutter(false);
      dev.digitizer.stop();
      throw;
    }
    event(msg::CmmEventKind::SweepEnd, label);
    samplePose();
    // Stop returns once the profiles the head made before it have arrived (the end of the sweep,
    // delivered late on a loaded host), or counts the ones that never came as lost.
    timed(spent.digitizer, [&] { dev.digitizer.stop(); });
    shutter(false);
    clockSync();
    r.motion_done += moveSeconds(sweep.start, sweep.end, sweep.speed, r.params.limits);
    r.at = sweep.end;
    return dev.digitizer.counters().lost_profiles - lost_at_start;
  }

  // The digitizer's profiles into the trace as they arrive (its reader thread).
  void startDigitizer(const drivers::digitizer::ConfigReply& config) {
    dev.digitizer.start([this, angle_min = config.angle_min, increment = config.angle_increment](
                            drivers::digitizer::Profile&& p) {
      msg::LaserProfile m;
      m.sequence = p.sequence;
      m.device_time_ns = static_cast<std::int64_t>(p.device_time_ns);
      m.status = p.status;
      m.angle_min = angle_min;
      m.angle_increment = increment;
      m.range = std::move(p.range);
      m.intensity = std::move(p.intensity);
      ++profiles;
      write(msg::topics::kLaserProfile, clock.now(), msg::encode(m));
    });
  }

  void park(Running& r) {
    report(r, r.plan.steps.size(), "parking");
    event(msg::CmmEventKind::MoveBegin, "park");
    move(r.safety, r.plan.park, r.plan.travel_speed);
    event(msg::CmmEventKind::MoveEnd, "park");
    samplePose();
    clockSync();
  }

  // A clean ending: nothing more moves, the laser is off, the trace says why it ends here.
  void endEarly(const std::string& reason) {
    try {
      dev.cmm.abort();
    } catch (const std::exception&) {
    }
    dev.digitizer.stop();
    try {
      shutter(false);
    } catch (const std::exception&) {
    }
    event(msg::CmmEventKind::Abort, reason);
  }
};

ScanRunner::ScanRunner(CellDevices devices, trace::TraceSink& sink, const StationClock& clock, ScanObserver* observer)
    : impl_(std::make_unique<Impl>(devices, sink, clock, observer)) {}

ScanRunner::~ScanRunner() = default;

ScanRunResult ScanRunner::run(const ScanPlan& plan, const ScanRunParams& params) { return impl_->run(plan, params); }

void ScanRunner::abort(const std::string& reason) {
  {
    std::lock_guard lock(impl_->abort_mutex);
    if (!impl_->abort_reason) impl_->abort_reason = reason;
  }
  try {
    impl_->dev.cmm.abort();
  } catch (const std::exception&) {
  }
}

}  // namespace stampscan::acquisition
