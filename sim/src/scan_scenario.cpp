#include "stampscan/sim/scan_scenario.hpp"

#include "stampscan/acquisition/calibration_plan.hpp"
#include "stampscan/acquisition/trace/rigid_pose.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/acquisition/trace/trace_messages.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <stdexcept>
#include <variant>

namespace stampscan::sim {

namespace msg = stampscan::trace;

namespace {

Vec3 vec(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }

}  // namespace

ScanParams::ScanParams() { setCell(acquisition::virtualCell()); }

void ScanParams::setCell(const acquisition::CellConfig& config) {
  constexpr double kDeg = std::numbers::pi / 180;
  cell = config.geometry;
  limits = config.limits;
  const acquisition::DigitizerDrawing& d = cell.digitizer;
  digitizer.points_per_profile = d.points_per_profile;
  digitizer.half_angle = 0.5 * d.fan_angle_deg * kDeg;
  digitizer.standoff = d.standoff_mm;
  digitizer.measuring_range = d.measuring_range_mm;
  digitizer.profile_rate = d.profile_rate_hz;
  digitizer.max_incidence = d.incidence_limit_deg * kDeg;
  digitizer.steep_from = std::min(digitizer.steep_from, 0.75 * digitizer.max_incidence);
  const trace::CameraIntrinsicsRecord c = acquisition::nominalIntrinsics(cell.cameras);
  camera.width = c.width;
  camera.height = c.height;
  camera.fx = c.fx;
  camera.fy = c.fy;
  camera.cx = c.cx;
  camera.cy = c.cy;
  camera.k1 = c.k1;
  camera.k2 = c.k2;
  camera.p1 = camera.p2 = camera.k3 = 0;
  camera_sensor.bits = cell.cameras.bits;
  stereo_standoff = cell.cameras.convergence_mm;
  sphere.centre = vec(cell.sphere.centre_mm);
  sphere.radius = 0.5 * cell.sphere.diameter_mm;
  has_second_sphere = cell.ball_bar.has_value();
  if (cell.ball_bar) {
    second_sphere.centre = vec(cell.ball_bar->centre_mm);
    second_sphere.radius = 0.5 * cell.ball_bar->diameter_mm;
  }
  plate.columns = cell.plate.columns;
  plate.rows = cell.plate.rows;
  plate.pitch = cell.plate.pitch_mm;
  plate.dot_diameter = cell.plate.dot_diameter_mm;
  plate.margin = cell.plate.pitch_mm;
}

ScanParams ScanParams::quick() {
  ScanParams p;
  p.image_scale = 0.25;
  p.stereo_rows = 1;
  p.stereo_columns = 2;
  p.plate_poses = 6;
  p.sphere_sweeps = 4;
  p.scan_region = {Vec2(-20, -15), Vec2(20, 15)};
  return p;
}

namespace {

std::int64_t toNs(double seconds) { return static_cast<std::int64_t>(std::llround(seconds * 1e9)); }

std::string number(double v) { return trace::formatNumber(v); }
std::string poseText(const Eigen::Isometry3d& T) { return trace::formatPose(trace::toRigidPose(T)); }
std::string intrinsicsText(const CameraIntrinsics& c) {
  trace::SessionDescription s;
  s.camera_nominal = c.record();
  return trace::encodeSession(s).at("camera_nominal_intrinsics");
}

Eigen::Matrix3d smallRotation(std::mt19937_64& rng, double sigma) {
  std::normal_distribution<double> g(0.0, sigma);
  const Vec3 w(g(rng), g(rng), g(rng));
  if (w.norm() < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
}

constexpr double kLoadSeconds = 1.0, kUnloadSeconds = 0.6;  // part loading and unloading, door open


// ---- The plan -----------------------------------------------------------------------------------
// What the cell does, as a plan both executors play (this simulator and the ScanRunner on a cell).

class Planner {
 public:
  explicit Planner(const ScanParams& p)
      : p_(p), part_(makePart(p)), mount_(nominalDigitizerMount(p)),
        rig_drop_(p.cell.cameras.drop_mm) {}

  acquisition::ScanPlan plan() {
    plan_.name = std::string(part_->name()) + (p_.calibration ? ", with calibration" : "");
    plan_.part.kind = part_->name();
    plan_.part.grid = toString(p_.grid.kind);
    plan_.part.pitch = p_.grid.pitch;
    plan_.part.circle_diameter = p_.grid.circle_diameter;
    plan_.part.line_width = p_.grid.line_width;
    plan_.travel_speed = 200;
    plan_.park = acquisition::parkingPose(p_.limits);
    // The calibration scenes, planned from the cell and placed as the station does for a real cell.
    acquisition::CalibrationScenes scenes;
    scenes.plate_views = p_.calibration ? p_.plate_poses : 0;
    scenes.sphere_sweeps = p_.calibration ? p_.sphere_sweeps : 0;
    scenes.second_sphere_sweeps = p_.has_second_sphere ? p_.second_sphere_sweeps : 0;
    scenes.seed = p_.seed;
    if (p_.laser) planLaserStrips();
    if (p_.stereo) planStereo();
    return acquisition::withCalibrationScenes(std::move(plan_), p_.cell, p_.limits, scenes);
  }

 private:
  static acquisition::HeadPose pose(const Vec3& head, double a, double b) { return {{head.x(), head.y(), head.z()}, a, b}; }

  // The head angle the head can take nearest to `angle`: an indexing head's nearest stop.
  double stop(double angle) const { return acquisition::nearestHeadStop(angle, p_.limits); }

  // Head position that puts the digitizer's mirror at `sensor` with head angles (a, b), using the
  // nominal mount (the planner does not know the true one).
  Vec3 headForSensor(const Vec3& sensor, double a, double b) const {
    const HeadState h{Vec3::Zero(), a, b, 0};
    return sensor - h.pose().linear() * mount_.translation();
  }
  // The direction the digitizer looks (its -z) and its fan's direction (x), machine frame.
  Eigen::Matrix3d sensorAxes(double a, double b) const {
    const HeadState h{Vec3::Zero(), a, b, 0};
    return h.pose().linear() * mount_.linear();
  }

  void sweep(acquisition::Scene scene, std::uint32_t index, const Vec3& sensor_from, const Vec3& sensor_to, double a, double b,
             double speed) {
    acquisition::SweepStep s;
    s.scene = scene;
    s.index = index;
    s.start = pose(headForSensor(sensor_from, a, b), a, b);
    s.end = pose(headForSensor(sensor_to, a, b), a, b);
    s.speed = speed;
    plan_.steps.emplace_back(s);
  }

  void view(acquisition::Scene scene, std::uint32_t index, const Vec3& head, double a, double b) {
    acquisition::StereoStep v;
    v.scene = scene;
    v.index = index;
    v.pose = pose(head, a, b);
    v.settle_s = 0.4;
    plan_.steps.emplace_back(v);
  }

  BlankRect region() const {
    const BlankRect whole = part_->footprint();
    if (p_.scan_region.max.x() <= p_.scan_region.min.x()) return whole;
    return {whole.min.cwiseMax(p_.scan_region.min), whole.max.cwiseMin(p_.scan_region.max)};
  }

  void planLaserStrips() {
    const BlankRect r = region();
    const DigitizerSpec& d = p_.digitizer;
    const double z_mid = 0.5 * (part_->minHeight() + part_->maxHeight());
    const double width = 2 * d.standoff * std::tan(d.half_angle);
    const double step = width * (1 - p_.strip_overlap);
    const int strips = std::max(1, static_cast<int>(std::ceil((r.max.x() - r.min.x()) / step)));
    const double x0 = 0.5 * (r.min.x() + r.max.x()) - 0.5 * (strips - 1) * step;
    // Beyond the region each strip runs on by an element's outline and the sweep's run-up, so that
    // the elements at the region's edge are crossed where the head's track can be trusted.
    const double lead = p_.grid.pitch + acquisition::sweepRunUp(p_.sweep_speed, acquisition::MachineLimits{}.acceleration);
    for (int k = 0; k < strips; ++k) {
      // Neighbouring strips cross at small angles (+-2 degrees), as in the paper's Sec. 3.1; an
      // indexing head's nearest stop may make them parallel.
      const double b = stop((k % 2 ? 2.0 : -2.0) * std::numbers::pi / 180);
      // The sensor over the strip's middle at its standoff along its own axis, moving along the
      // fan's normal (its y).
      const Eigen::Matrix3d R = sensorAxes(0, b);
      const Vec3 along = Vec3(R(0, 1), R(1, 1), 0).normalized();
      const Vec3 centre = Vec3(x0 + k * step, 0.5 * (r.min.y() + r.max.y()), z_mid) + d.standoff * R.col(2);
      const double half = 0.5 * (r.max.y() - r.min.y()) + lead;
      const double direction = k % 2 ? -1.0 : 1.0;
      sweep(acquisition::Scene::Part, static_cast<std::uint32_t>(k), centre - direction * half * along,
            centre + direction * half * along, 0, b, p_.sweep_speed);
    }
  }

  void planStereo() {
    const BlankRect r = region();
    const double z_mid = 0.5 * (part_->minHeight() + part_->maxHeight());
    const Vec2 mid = 0.5 * (r.min + r.max);
    const Vec2 half = 0.5 * (r.max - r.min);
    const int rows = std::max(1, p_.stereo_rows), cols = std::max(1, p_.stereo_columns);
    std::uint32_t index = 0;
    const double max_reach = half.norm() + 1e-9;
    for (int j = 0; j < rows; ++j)
      for (int i = 0; i < cols; ++i) {
        const double fx = cols == 1 ? 0.0 : 2.0 * i / (cols - 1) - 1.0;
        const double fy = rows == 1 ? 0.0 : 2.0 * j / (rows - 1) - 1.0;
        const Vec2 at = mid + Vec2(fx * 0.6 * half.x(), fy * 0.6 * half.y());
        // Outer views stand further out and look inwards, so that the walls are seen too.
        const Vec2 offset = at - Vec2::Zero();
        const double reach = std::min(1.0, offset.norm() / max_reach);
        const double a = stop(0.35 * reach);
        const double phi = std::atan2(offset.y(), offset.x());
        const double b = stop(reach > 1e-6 ? std::atan2(std::cos(phi), -std::sin(phi)) : 0.0);
        const HeadState h{Vec3::Zero(), a, b, 0};
        const Vec3 target(at.x(), at.y(), z_mid);
        const Vec3 head = target + h.pose().linear() * Vec3(0, 0, rig_drop_ + p_.stereo_standoff);
        view(acquisition::Scene::Part, index++, head, a, b);
      }
  }

  const ScanParams& p_;
  std::unique_ptr<FormedPart> part_;
  Eigen::Isometry3d mount_;  // the digitizer's nominal mount
  double rig_drop_;          // mm: the stereo pair below the head's reference point
  acquisition::ScanPlan plan_;
};

// The cell's true geometry and clocks for a seed: what calibration has to recover. The simulated
// sessions and the virtual cell draw it alike, so one seed is one cell.
CellTruth drawTruth(const ScanParams& p) {
  CellTruth truth;
  std::mt19937_64 rng(p.seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const CameraIntrinsics nominal = p.camera.scaled(p.image_scale);
  for (CameraIntrinsics* c : {&truth.left, &truth.right}) {
    *c = nominal;
    c->fx *= 1 + 0.004 * g(rng);
    c->fy = c->fx * (1 + 0.0005 * g(rng));
    // The principal point off its drawing by about 28 um on the sensor: 8 px of 3.45 um pixels.
    const double pixel_um = p.cell.cameras.pixel_size_um / p.image_scale;
    c->cx += 8 * (3.45 / pixel_um) * g(rng);
    c->cy += 8 * (3.45 / pixel_um) * g(rng);
    c->k1 += 0.01 * g(rng);
    c->k2 += 0.02 * g(rng);
    c->p1 = 2e-4 * g(rng);
    c->p2 = 2e-4 * g(rng);
  }
  Eigen::Isometry3d left = trace::toIsometry(acquisition::nominalCameraMount(p.cell.cameras, 0));
  Eigen::Isometry3d right = trace::toIsometry(acquisition::nominalCameraMount(p.cell.cameras, 1));
  for (Eigen::Isometry3d* T : {&left, &right}) {
    T->linear() = smallRotation(rng, 0.003) * T->linear();
    T->translation() += Vec3(0.3 * g(rng), 0.3 * g(rng), 0.3 * g(rng));
  }
  truth.head_from_left = left;
  truth.head_from_right = right;
  truth.head_from_digitizer_nominal = nominalDigitizerMount(p);
  truth.head_from_digitizer = truth.head_from_digitizer_nominal;
  truth.head_from_digitizer.linear() = smallRotation(rng, 0.008) * truth.head_from_digitizer_nominal.linear();
  truth.head_from_digitizer.translation() += Vec3(g(rng), g(rng), g(rng));
  truth.digitizer_clock_offset_ns = toNs(1 + 99 * u(rng));
  // Within a millisecond of the drawing's latency.
  truth.digitizer_latency_ns = toNs(std::max(0.0, 1e-3 * p.cell.digitizer.latency_ms + 0.002 * (u(rng) - 0.5)));
  truth.camera_clock_offset_ns[0] = toNs(10 + 1000 * u(rng));
  truth.camera_clock_offset_ns[1] = toNs(10 + 1000 * u(rng));
  truth.sphere = p.sphere;
  truth.head_from_digitizer.translation() += p.digitizer_mount_shift;  // after the draws: the seed's cell otherwise
  return truth;
}

// Messages collected for a stretch of the session and released in log-time order once nothing
// earlier can still arrive.
class OrderedEmitter {
 public:
  explicit OrderedEmitter(TraceSink& sink) : sink_(sink) {}
  void add(std::string_view topic, std::int64_t log_time, std::vector<std::byte> bytes) {
    pending_.push_back({log_time, order_++, topic, std::move(bytes)});
  }
  void flushBefore(std::int64_t t) {
    std::stable_sort(pending_.begin(), pending_.end(),
                     [](const Pending& a, const Pending& b) { return a.log < b.log || (a.log == b.log && a.order < b.order); });
    std::size_t n = 0;
    while (n < pending_.size() && pending_[n].log < t) {
      sink_.message(pending_[n].topic, pending_[n].log, std::move(pending_[n].bytes));
      ++n;
    }
    emitted_ += n;
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
  }
  std::size_t emitted() const { return emitted_; }

 private:
  struct Pending {
    std::int64_t log;
    std::uint64_t order;
    std::string_view topic;
    std::vector<std::byte> bytes;
  };
  TraceSink& sink_;
  std::vector<Pending> pending_;
  std::uint64_t order_ = 0;
  std::size_t emitted_ = 0;
};

// What the cell does during one segment of the CMM's trajectory.
struct Activity {
  enum Kind { Travel, Sweep, Trigger } kind = Travel;
  const Scene* scene = nullptr;
  acquisition::Scene plan_scene = acquisition::Scene::Part;  // the step's scene, for its marker (a travel has none)
  std::uint32_t index = 0;
  bool first_of_scene = false, last_of_scene = false;
};

class SessionGenerator {
 public:
  SessionGenerator(const ScanParams& params, TraceSink& sink, const ScanProgress& progress)
      : p_(params), sink_(sink), progress_(progress), emitter_(sink), rng_(params.seed) {}

  ScanSummary run() {
    part_ = makePart(p_);
    part_scene_ = std::make_unique<PartScene>(*part_, p_.grid, machineFromDatum(p_));
    sphere_scene_ = std::make_unique<SphereScene>(p_.sphere);
    second_sphere_scene_ = std::make_unique<SphereScene>(p_.second_sphere);
    plate_scene_ = std::make_unique<PlateScene>(p_.plate, platePose(p_));
    makeTruth();
    // The planner plans the part in its datum frame; the session runs it on the fixture.
    plan_ = acquisition::placeOnFixture(planScan(p_), p_.cell, p_.limits.index_step);
    const acquisition::ScanPlan& plan = plan_;
    const Vec3 park(plan.park.position[0], plan.park.position[1], plan.park.position[2]);
    trajectory_ = CmmTrajectory({}, HeadState{park, 0, 0, 0});
    // The operator loads the part: the door is open, then closes, then the clamp closes; the CMM
    // waits for both (the PLC's timeline below).
    trajectory_.dwell(kLoadSeconds, "load part");
    addSegment({});
    play(plan);
    trajectory_.moveTo(park, 0, 0, plan.travel_speed, "home");
    activities_.emplace_back();
    trajectory_.dwell(kUnloadSeconds, "unload part");
    addSegment({});
    writeMetadata();
    play();
    summary_.scan_seconds = trajectory_.duration();
    summary_.messages = emitter_.emitted();
    summary_.grid_elements = gridElements(p_.grid, part_->blank()).size();
    summary_.truth = truth_;
    return summary_;
  }

 private:
  const Scene* sceneNamed(acquisition::Scene name) const {
    if (name == acquisition::Scene::Part) return part_scene_.get();
    if (name == acquisition::Scene::ReferenceSphere) return sphere_scene_.get();
    if (name == acquisition::Scene::SecondSphere) return second_sphere_scene_.get();
    return plate_scene_.get();
  }

  // The plan's steps as moves of the simulated CMM: the same plan the ScanRunner plays on a cell.
  void play(const acquisition::ScanPlan& plan) {
    auto sceneOf = [&](std::size_t k) -> std::optional<acquisition::Scene> {
      if (k >= plan.steps.size()) return std::nullopt;
      return std::visit([](const auto& step) { return step.scene; }, plan.steps[k]);
    };
    for (std::size_t k = 0; k < plan.steps.size(); ++k) {
      const acquisition::Scene scene = *sceneOf(k);
      const bool first = k == 0 || sceneOf(k - 1) != scene, last = sceneOf(k + 1) != scene;
      if (const auto* w = std::get_if<acquisition::SweepStep>(&plan.steps[k])) {
        travelTo(toVec(w->start), w->start.a, w->start.b, plan.travel_speed);
        trajectory_.moveTo(toVec(w->end), w->end.a, w->end.b, w->speed, trace::sweepLabel(scene, w->index));
        addSegment({Activity::Sweep, sceneNamed(scene), scene, w->index, first, last});
      } else {
        const auto& v = std::get<acquisition::StereoStep>(plan.steps[k]);
        if (scene == acquisition::Scene::CalibrationPlate) truth_.plate_poses.push_back(platePose(p_));
        travelTo(toVec(v.pose), v.pose.a, v.pose.b, plan.travel_speed);
        trajectory_.dwell(v.settle_s, "settle and trigger");
        addSegment({Activity::Trigger, sceneNamed(scene), scene, v.index, first, last});
      }
    }
  }

  static Vec3 toVec(const acquisition::HeadPose& p) { return {p.position[0], p.position[1], p.position[2]}; }

  const ScanParams& params() const { return p_; }

  void makeTruth() { truth_ = drawCellTruth(p_); }

  void addSegment(Activity activity) { activities_.push_back(std::move(activity)); }

  void travelTo(const Vec3& head, double a, double b, double speed) {
    trajectory_.moveTo(head, a, b, speed, "travel");
    addSegment({});
  }

  void writeMetadata() {
    trace::SessionDescription cell = describeSession(p_);
    cell.part = part_->name();
    // The plan this session plays, whole, so that a replay runs it again.
    const acquisition::ScanPlan& plan = plan_;
    cell.plan = plan.name;
    cell.plan_toml = acquisition::toToml(plan);
    sink_.metadata(std::string(trace::kSessionMetadataName), trace::encodeSession(cell));
    std::map<std::string, std::string> truth = {
        {"seed", std::to_string(p_.seed)},
        {"camera_left_intrinsics", intrinsicsText(truth_.left)},
        {"camera_right_intrinsics", intrinsicsText(truth_.right)},
        {"head_from_camera_left", poseText(truth_.head_from_left)},
        {"head_from_camera_right", poseText(truth_.head_from_right)},
        {"stereo_baseline_mm", number((truth_.head_from_left.translation() - truth_.head_from_right.translation()).norm())},
        {"head_from_digitizer", poseText(truth_.head_from_digitizer)},
        {"digitizer_clock_offset_ns", std::to_string(truth_.digitizer_clock_offset_ns)},
        {"digitizer_latency_ns", std::to_string(truth_.digitizer_latency_ns)},
        {"camera_left_clock_offset_ns", std::to_string(truth_.camera_clock_offset_ns[0])},
        {"camera_right_clock_offset_ns", std::to_string(truth_.camera_clock_offset_ns[1])},
        {"reference_sphere_centre_mm", number(p_.sphere.centre.x()) + " " + number(p_.sphere.centre.y()) + " " +
                                           number(p_.sphere.centre.z())},
    };
    for (std::size_t k = 0; k < truth_.plate_poses.size(); ++k)
      truth["plate_pose_" + std::to_string(k)] = poseText(truth_.plate_poses[k]);
    sink_.metadata("simulation_truth", truth);
  }

  // ---- Playing the plan ------------------------------------------------------------------------

  void play() {
    const auto& segments = trajectory_.segments();
    double work_total = 0;
    for (std::size_t s = 0; s < segments.size(); ++s) work_total += workOf(s);
    double work_done = 0;
    std::normal_distribution<double> jitter(0.0, 1.0);
    std::int64_t next_position = 0, next_plc = 0, next_sync = 0;
    const std::int64_t position_period = toNs(1.0 / 250), plc_period = toNs(0.1), sync_period = toNs(1.0);
    for (std::size_t s = 0; s < segments.size(); ++s) {
      const auto& seg = segments[s];
      const Activity& act = activities_[s];
      const std::int64_t t0 = toNs(seg.t0), t1 = toNs(seg.t1);
      if (progress_) progress_(work_done / std::max(work_total, 1e-9), act.kind == Activity::Travel ? std::string("moving") : std::string(toString(act.plan_scene)));
      // CMM events and scene markers.
      if (act.kind != Activity::Travel && act.first_of_scene) marker(t0, act.plan_scene, "begin", act.index);
      event(t0, act.kind == Activity::Sweep ? msg::CmmEventKind::SweepBegin : msg::CmmEventKind::MoveBegin, seg.label);
      // Position reports at 250 Hz, PLC state at 10 Hz, clock pairs once a second.
      for (; next_position < t1; next_position += position_period) {
        const HeadState h = trajectory_.at(static_cast<double>(next_position) * 1e-9);
        msg::CmmPosition m;
        m.station_time_ns = kSessionStartNs + next_position;
        m.x = h.position.x() + 0.0005 * jitter(rng_);
        m.y = h.position.y() + 0.0005 * jitter(rng_);
        m.z = h.position.z() + 0.0005 * jitter(rng_);
        m.head_a = h.a;
        m.head_b = h.b;
        ++summary_.positions;
        emitter_.add(msg::topics::kCmmPosition, m.station_time_ns + toNs(0.002), msg::encode(m));
      }
      for (; next_plc < t1; next_plc += plc_period) plc(next_plc, act.kind == Activity::Sweep);
      for (; next_sync < t1; next_sync += sync_period) clockSyncs(next_sync, jitter);
      if (act.kind == Activity::Sweep) profiles(seg, act);
      if (act.kind == Activity::Trigger) frames(seg, act);
      event(t1, act.kind == Activity::Sweep ? msg::CmmEventKind::SweepEnd : msg::CmmEventKind::MoveEnd, seg.label);
      if (act.kind != Activity::Travel && act.last_of_scene) marker(t1, act.plan_scene, "end", act.index);
      emitter_.flushBefore(kSessionStartNs + t1);
      work_done += workOf(s);
    }
    emitter_.flushBefore(std::numeric_limits<std::int64_t>::max());
    if (progress_) progress_(1.0, "done");
  }

  double workOf(std::size_t s) const {
    const Activity& act = activities_[s];
    const auto& seg = trajectory_.segments()[s];
    if (act.kind == Activity::Sweep)
      return (seg.t1 - seg.t0) * p_.digitizer.profile_rate * p_.digitizer.points_per_profile;
    if (act.kind == Activity::Trigger) return 2.0 * truth_.left.width * truth_.left.height;
    return 0;
  }

  void event(std::int64_t t, msg::CmmEventKind kind, const std::string& detail) {
    msg::CmmEvent e;
    e.station_time_ns = kSessionStartNs + t;
    e.kind = kind;
    e.detail = detail;
    emitter_.add(msg::topics::kCmmEvent, e.station_time_ns + toNs(0.002), msg::encode(e));
  }

  void marker(std::int64_t t, acquisition::Scene scene, const char* phase, std::uint32_t index) {
    msg::SceneMarker m;
    m.station_time_ns = kSessionStartNs + t;
    m.scene = scene;
    m.phase = phase;
    m.index = index;
    emitter_.add(msg::topics::kScene, m.station_time_ns, msg::encode(m));
  }

  void plc(std::int64_t t, bool shutter_open) {
    // The timeline: door open while the part is loaded, closed at 0.5 s, clamp closed at 0.8 s; at
    // the end the clamp opens, then the door.
    const double seconds = static_cast<double>(t) * 1e-9, end = trajectory_.duration();
    msg::PlcState s;
    s.station_time_ns = kSessionStartNs + t;
    s.door_closed = seconds >= 0.5 && seconds < end - 0.2;
    s.estop_ok = true;
    s.light_curtain_clear = s.door_closed;
    s.part_clamped = seconds >= 0.8 && seconds < end - 0.4;
    s.laser_shutter_open = shutter_open;
    s.stack_light = shutter_open ? 0b010 : 0b001;
    s.heartbeat = plc_heartbeat_++;
    emitter_.add(msg::topics::kPlcState, s.station_time_ns + toNs(0.001), msg::encode(s));
  }

  void clockSyncs(std::int64_t t, std::normal_distribution<double>& jitter) {
    const std::pair<const char*, std::int64_t> devices[] = {{"digitizer", truth_.digitizer_clock_offset_ns},
                                                            {"camera_left", truth_.camera_clock_offset_ns[0]},
                                                            {"camera_right", truth_.camera_clock_offset_ns[1]}};
    for (const auto& [name, offset] : devices) {
      msg::ClockSync c;
      c.device = name;
      c.station_time_ns = kSessionStartNs + t;
      c.device_time_ns = c.station_time_ns + offset + toNs(20e-6 * jitter(rng_));  // 20 us of jitter
      emitter_.add(msg::topics::kClockSync, c.station_time_ns + toNs(0.001), msg::encode(c));
    }
  }

  void profiles(const CmmTrajectory::Segment& seg, const Activity& act) {
    const DigitizerSpec& d = p_.digitizer;
    const double period = 1.0 / d.profile_rate;
    const double first = std::ceil(seg.t0 / period) * period;
    const int count = std::max(0, static_cast<int>(std::floor((seg.t1 - first) / period)) + 1);
    std::vector<msg::LaserProfile> out(static_cast<std::size_t>(count));
    const std::uint32_t base = profile_sequence_;
    tbb::parallel_for(0, count, [&](int k) {
      const double t = first + k * period;
      const Eigen::Isometry3d sensor = trajectory_.at(t).pose() * truth_.head_from_digitizer;
      // Each profile draws from its own stream: the same result for any number of threads.
      std::mt19937_64 rng(p_.seed * 0x9E3779B97F4A7C15ull + 0x5EEDull + base + static_cast<std::uint64_t>(k));
      ProfileMeasurement m = measureProfile(*act.scene, d, sensor, rng);
      msg::LaserProfile& prof = out[static_cast<std::size_t>(k)];
      prof.sequence = base + static_cast<std::uint32_t>(k);
      prof.device_time_ns = kSessionStartNs + toNs(t) + truth_.digitizer_clock_offset_ns + truth_.digitizer_latency_ns;
      prof.status = m.glare ? msg::kProfileOverexposed : msg::kProfileOk;
      prof.angle_min = static_cast<float>(d.angle(0));
      prof.angle_increment = static_cast<float>(d.angleIncrement());
      prof.range = std::move(m.range);
      prof.intensity = std::move(m.intensity);
    });
    profile_sequence_ += static_cast<std::uint32_t>(count);
    for (int k = 0; k < count; ++k) {
      const msg::LaserProfile& prof = out[static_cast<std::size_t>(k)];
      const double t = first + k * period;
      summary_.laser_points += static_cast<std::size_t>(
          std::count_if(prof.range.begin(), prof.range.end(), [](float r) { return r > 0; }));
      // It reaches the station over USB a little after its stamp.
      emitter_.add(msg::topics::kLaserProfile, kSessionStartNs + toNs(t) + truth_.digitizer_latency_ns + toNs(0.001),
                   msg::encode(prof));
    }
    summary_.profiles += static_cast<std::size_t>(count);
  }

  void frames(const CmmTrajectory::Segment& seg, const Activity& act) {
    const double t = seg.t0 + 0.1;  // settled
    const Eigen::Isometry3d head = trajectory_.at(t).pose();
    const std::uint64_t trigger_id = ++trigger_id_;
    for (int c = 0; c < 2; ++c) {
      const CameraIntrinsics& in = c == 0 ? truth_.left : truth_.right;
      const Eigen::Isometry3d camera = head * (c == 0 ? truth_.head_from_left : truth_.head_from_right);
      if (!renderers_[c]) renderers_[c] = std::make_unique<CameraRenderer>(in);
      const GrayImage image = renderers_[c]->render(*act.scene, p_.camera_sensor, camera,
                                                    p_.seed * 1000003ull + trigger_id * 2 + static_cast<std::uint64_t>(c));
      msg::CameraFrame f;
      f.camera = c == 0 ? "left" : "right";
      f.frame_id = ++frame_id_[c];
      f.trigger_id = trigger_id;
      f.device_time_ns = kSessionStartNs + toNs(t + 15e-6) + truth_.camera_clock_offset_ns[c];
      f.width = static_cast<std::uint32_t>(image.width);
      f.height = static_cast<std::uint32_t>(image.height);
      f.encoding = image.bits == 8 ? "mono8" : "mono16";
      f.step = f.width * (image.bits == 8 ? 1u : 2u);
      f.data = image.bytes();
      ++summary_.frames;
      // Exposure, readout and transfer over GigE: the frame arrives some 40 ms after the trigger.
      emitter_.add(c == 0 ? msg::topics::kCameraLeft : msg::topics::kCameraRight,
                   kSessionStartNs + toNs(t + 0.040 + 0.002 * c), msg::encode(f));
    }
  }

  const ScanParams& p_;
  TraceSink& sink_;
  const ScanProgress& progress_;
  OrderedEmitter emitter_;
  std::mt19937_64 rng_;
  std::unique_ptr<FormedPart> part_;
  std::unique_ptr<PartScene> part_scene_;
  acquisition::ScanPlan plan_;
  std::unique_ptr<SphereScene> sphere_scene_, second_sphere_scene_;
  std::unique_ptr<PlateScene> plate_scene_;
  std::unique_ptr<CameraRenderer> renderers_[2];  // made at the first frame: the pixel rays are cached
  CellTruth truth_;
  CmmTrajectory trajectory_;
  std::vector<Activity> activities_;
  ScanSummary summary_;
  std::uint32_t profile_sequence_ = 0, plc_heartbeat_ = 0;
  std::uint64_t trigger_id_ = 0, frame_id_[2] = {1000, 5000};
};

}  // namespace

acquisition::ScanPlan planScan(const ScanParams& params) { return Planner(params).plan(); }

Eigen::Isometry3d machineFromDatum(const ScanParams& params) {
  return trace::toIsometry(acquisition::toRigidPose(params.cell.fixture.datum));
}

Eigen::Isometry3d platePose(const ScanParams& params) { return trace::toIsometry(acquisition::machineFromPlate(params.cell.plate)); }

CellTruth drawCellTruth(const ScanParams& params) { return drawTruth(params); }

trace::SessionDescription describeSession(const ScanParams& p) {
  acquisition::CellGeometry cell = p.cell;
  cell.cameras = acquisition::atResolution(cell.cameras, p.image_scale);
  acquisition::ScanPlan plan;  // the part and its grid; the plan itself is the caller's
  plan.part.kind = p.part == PartKind::Dome ? "dome" : "pan";
  plan.part.grid = toString(p.grid.kind);
  plan.part.pitch = p.grid.pitch;
  plan.part.circle_diameter = p.grid.circle_diameter;
  plan.part.line_width = p.grid.line_width;
  trace::SessionDescription session = acquisition::describeSession(cell, plan);
  session.plan.clear();
  return session;
}

Eigen::Isometry3d nominalDigitizerMount(const ScanParams& params) {
  return trace::toIsometry(acquisition::toRigidPose(params.cell.digitizer.mount));
}

std::unique_ptr<FormedPart> makePart(const ScanParams& params) {
  if (params.part == PartKind::Dome) return std::make_unique<DomePart>(params.dome);
  return std::make_unique<StampedPanPart>(params.pan);
}

ScanSummary generateScan(const ScanParams& params, TraceSink& sink, const ScanProgress& progress) {
  SessionGenerator generator(params, sink, progress);
  return generator.run();
}

}  // namespace stampscan::sim
