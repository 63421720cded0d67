#include "stampscan/jobs/calibrate_job.hpp"

#include "stampscan/jobs/calibration_results.hpp"
#include "stampscan/acquisition/calibration_plan.hpp"

#include "stampscan/fitting/median.hpp"

#include "stampscan/registration/digitizer_calibration.hpp"
#include "stampscan/registration/measure_scan.hpp"
#include "stampscan/registration/scan_trace.hpp"
#include "stampscan/registration/sphere_verification.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace stampscan::jobs {

namespace fs = std::filesystem;
using registration::RecordCheck;
using registration::RecordValue;

namespace {

constexpr double kDegPerRad = 180 / 3.14159265358979323846;

std::string format(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

double angleDeg(const Eigen::Matrix3d& r) { return Eigen::AngleAxisd(r).angle() * kDegPerRad; }

// The jackknife's standard uncertainty of each component of a leave-one-out series of vectors.
std::vector<double> jackknifeSds(const std::vector<std::vector<double>>& leave_one_out) {
  std::vector<double> out;
  if (leave_one_out.empty()) return out;
  for (std::size_t k = 0; k < leave_one_out.front().size(); ++k) {
    std::vector<double> component;
    for (const auto& v : leave_one_out) component.push_back(v[k]);
    out.push_back(registration::jackknifeSd(component));
  }
  return out;
}

// The same for a rotation, from the leave-one-out rotations' angles away from the full fit (a
// rotation has no mean to subtract; the full fit stands in for it).
double jackknifeAngleSd(const std::vector<double>& angles_deg) {
  const double n = static_cast<double>(angles_deg.size());
  if (n < 2) return 0;
  double ss = 0;
  for (double a : angles_deg) ss += a * a;
  return std::sqrt((n - 1) / n * ss);
}

std::vector<registration::SensorIdentity> sensorsOf(const acquisition::ScanRunResult& run, const std::string& family) {
  std::vector<registration::SensorIdentity> out;
  for (const auto& d : run.devices)
    if (d.family == family) out.push_back({d.family, d.model, d.serial, d.firmware});
  return out;
}

// ---- The digitizer: mount and latency on the sphere sweeps -------------------------------------

struct DigitizerOutcome {
  registration::SphereCalibrationResult fit;
  std::vector<std::string> left_out;
  std::size_t sweeps_used = 0;
  std::vector<double> sd;  // mount x, y, z (mm), rotation (deg), latency (ms)
};

// A sweep's points against the fitted sphere: how many lie on it (within 1 mm) and their radial RMS.
std::pair<std::size_t, double> sweepOnSphere(const std::vector<registration::Profile>& profiles,
                                             const registration::HeadTrack& track,
                                             const registration::SphereCalibrationResult& fit, double radius) {
  std::size_t n = 0;
  double ss = 0;
  for (const registration::Vec3& p : registration::spherePoints(profiles, track, fit.calibration)) {
    const double d = (p - fit.sphere_centre).norm() - radius;
    if (std::abs(d) > 1.0) continue;
    ++n;
    ss += d * d;
  }
  return {n, n ? std::sqrt(ss / static_cast<double>(n)) : 0.0};
}

DigitizerOutcome calibrateDigitizerOn(const registration::ScanTrace& trace, const acquisition::CalibrationPolicy& policy) {
  const trace::SessionDescription& session = *trace.session;
  if (!session.reference_sphere_radius_mm)
    throw std::runtime_error("the cell's description gives no reference-sphere radius: the digitizer cannot be calibrated");
  const auto pairs = trace.clock_pairs.find("digitizer");
  if (pairs == trace.clock_pairs.end()) throw std::runtime_error("the calibration trace has no clock pairs for the digitizer");
  const registration::HeadTrack track(trace.head);
  registration::SphereCalibrationParams sp;
  sp.sphere_radius = *session.reference_sphere_radius_mm;
  sp.nominal.head_from_digitizer = trace::toIsometry(session.head_from_digitizer_nominal);
  sp.nominal.clock_offset_ns = registration::clockOffset(pairs->second);
  const std::vector<std::vector<registration::Profile>> sweeps = registration::sphereSweepProfiles(
      trace, track, sp.nominal.clock_offset_ns, 0, registration::MeasureParams{}.max_track_error_mm);
  std::vector<std::string> labels;
  for (const auto& w : trace.sweeps)
    if (w.is(acquisition::Scene::ReferenceSphere)) labels.push_back(w.label);
  std::vector<std::size_t> kept(sweeps.size());
  for (std::size_t i = 0; i < kept.size(); ++i) kept[i] = i;
  const auto calibrateOn = [&](const std::vector<std::size_t>& use) {
    std::vector<registration::Profile> profiles;
    for (std::size_t i : use) profiles.insert(profiles.end(), sweeps[i].begin(), sweeps[i].end());
    return registration::calibrateDigitizer(profiles, track, sp);
  };

  DigitizerOutcome out;
  // A sweep that spoils the fit shows against the fit of all: few points on the sphere (it was
  // mostly outside the fan or the measuring range) or points that stand off it. It is left out and
  // the fit made again; twice at most, since a second round sees the first one's outliers gone.
  for (int round = 0; round < 2; ++round) {
    if (kept.size() < 4)
      throw std::runtime_error(format("only %zu reference-sphere sweeps measure the sphere; at least 4 are needed",
                                      kept.size()));
    out.fit = calibrateOn(kept);
    std::vector<std::pair<std::size_t, double>> stats;
    std::vector<double> counts, rmss;
    for (std::size_t i : kept) {
      stats.push_back(sweepOnSphere(sweeps[i], track, out.fit, sp.sphere_radius));
      counts.push_back(static_cast<double>(stats.back().first));
      rmss.push_back(stats.back().second);
    }
    const double median_count = fitting::medianOr(counts, 0.0), median_rms = fitting::medianOr(rmss, 0.0);
    std::vector<std::size_t> next;
    for (std::size_t k = 0; k < kept.size(); ++k) {
      const std::string name = kept[k] < labels.size() ? labels[kept[k]] : "sphere sweep " + std::to_string(kept[k]);
      // The plan's sweeps differ by design (fan positions, depths, angles), and a sweep that sees
      // a quarter of what another sees is normal; one that sees a tenth barely had the sphere in
      // its fan or its measuring range, and its few points are mostly the sphere's rim.
      if (static_cast<double>(stats[k].first) < 0.1 * median_count)
        out.left_out.push_back(format("%s: %zu points on the sphere against a median of %.0f (the sphere mostly outside "
                                      "the fan or the measuring range)", name.c_str(), stats[k].first, median_count));
      else if (stats[k].second > std::max(3 * median_rms, policy.digitizer_residual_mm))
        out.left_out.push_back(format("%s: its points stand %.4f mm RMS off the fitted sphere against a median of %.4f mm",
                                      name.c_str(), stats[k].second, median_rms));
      else
        next.push_back(kept[k]);
    }
    if (next.size() == kept.size()) break;
    kept = next;
    if (round == 1) out.fit = calibrateOn(kept);
  }
  out.sweeps_used = kept.size();
  // Each kept sweep left out once.
  std::vector<std::vector<double>> jack;
  std::vector<double> turned;
  for (std::size_t leave = 0; leave < kept.size(); ++leave) {
    std::vector<std::size_t> use;
    for (std::size_t k = 0; k < kept.size(); ++k)
      if (k != leave) use.push_back(kept[k]);
    const registration::DigitizerCalibration c = calibrateOn(use).calibration;
    const Eigen::Vector3d t = c.head_from_digitizer.translation();
    jack.push_back({t.x(), t.y(), t.z(), static_cast<double>(c.latency_ns) * 1e-6});
    turned.push_back(angleDeg(c.head_from_digitizer.linear() * out.fit.calibration.head_from_digitizer.linear().transpose()));
  }
  const std::vector<double> sd = jackknifeSds(jack);
  out.sd = {sd[0], sd[1], sd[2], jackknifeAngleSd(turned), sd[3]};
  return out;
}

registration::CalibrationRecord digitizerRecord(const DigitizerOutcome& d, const acquisition::CalibrationPolicy& policy,
                                                const std::optional<registration::DigitizerCalibrationFile>& previous,
                                                std::vector<std::string>& drift) {
  registration::CalibrationRecord r;
  r.kind = "digitizer";
  const registration::DigitizerCalibration& c = d.fit.calibration;
  const Eigen::Vector3d t = c.head_from_digitizer.translation();
  r.parameters = {{"digitizer mount x", t.x(), "mm", d.sd[0]},
                  {"digitizer mount y", t.y(), "mm", d.sd[1]},
                  {"digitizer mount z", t.z(), "mm", d.sd[2]},
                  {"digitizer mount rotation", angleDeg(c.head_from_digitizer.linear()), "deg", d.sd[3]},
                  {"digitizer latency", static_cast<double>(c.latency_ns) * 1e-6, "ms", d.sd[4]},
                  {"sphere centre x", d.fit.sphere_centre.x(), "mm", 0},
                  {"sphere centre y", d.fit.sphere_centre.y(), "mm", 0},
                  {"sphere centre z", d.fit.sphere_centre.z(), "mm", 0}};
  r.residuals = {{"sphere residual RMS", d.fit.rms_mm, "mm", 0},
                 {"points used", static_cast<double>(d.fit.inliers), "", 0},
                 {"sphere sweeps used", static_cast<double>(d.sweeps_used), "", 0}};
  r.checks.push_back({"sphere residual RMS (digitizer)", d.fit.rms_mm, policy.digitizer_residual_mm, "mm",
                      d.fit.rms_mm <= policy.digitizer_residual_mm});
  if (previous) {
    const registration::DigitizerCalibration& p = previous->calibration;
    const double moved = (t - p.head_from_digitizer.translation()).norm();
    const double turned = angleDeg(c.head_from_digitizer.linear() * p.head_from_digitizer.linear().transpose());
    const double latency = static_cast<double>(c.latency_ns - p.latency_ns) * 1e-6;
    r.parameters.push_back({"digitizer mount change", moved, "mm", 0});
    r.parameters.push_back({"digitizer mount rotation change", turned, "deg", 0});
    r.parameters.push_back({"digitizer latency change", latency, "ms", 0});
    if (moved > policy.drift_mount_mm)
      drift.push_back(format("the digitizer's mount moved %.3f mm since %s (drift limit %.3f mm)", moved,
                             previous->provenance.record_id.empty() ? previous->created.c_str()
                                                                    : previous->provenance.record_id.c_str(),
                             policy.drift_mount_mm));
    if (std::abs(latency) > policy.drift_latency_ms)
      drift.push_back(format("the digitizer's latency changed %+.3f ms (drift limit %.3f ms)", latency, policy.drift_latency_ms));
  }
  return r;
}

// ---- The cameras: each camera, the pair, the left camera's mount on the head --------------------

struct CameraOutcome {
  registration::CameraRigCalibration rig;
  std::vector<std::string> left_out;
  std::vector<double> mount_sd;  // x, y, z (mm), rotation (deg)
};

CameraOutcome calibrateCamerasOn(const registration::ScanTrace& trace) {
  const std::size_t min_views = registration::MeasureParams{}.min_plate_views;
  std::optional<registration::CameraRigCalibration> rig = registration::calibrateCameraRig(trace, min_views);
  if (!rig)
    throw std::runtime_error(format("the calibration has %zu plate views; the cameras need at least %zu",
                                    trace.plate_left.size(), min_views));
  if (!rig->head_from_left)
    throw std::runtime_error("the head track does not cover 3 plate views: the cameras' mount on the head cannot be "
                             "calibrated (are the CMM's move reports recorded?)");
  CameraOutcome out;
  for (const auto* camera : {&rig->stereo.left, &rig->stereo.right})
    for (const registration::ViewReport& v : camera->views)
      if (!v.used)
        out.left_out.push_back(format("%s camera, plate view %zu: %s", camera == &rig->stereo.left ? "left" : "right",
                                      v.view, v.note.c_str()));
  std::vector<std::vector<double>> jack;
  std::vector<double> turned;
  const std::size_t n = rig->machine_from_head.size();
  if (n >= 4)
    for (std::size_t leave = 0; leave < n; ++leave) {
      std::vector<Eigen::Isometry3d> heads, plates;
      for (std::size_t k = 0; k < n; ++k)
        if (k != leave) {
          heads.push_back(rig->machine_from_head[k]);
          plates.push_back(rig->camera_from_plate[k]);
        }
      const Eigen::Isometry3d m = registration::calibrateHeadToCamera(heads, plates).head_from_camera;
      turned.push_back(angleDeg(m.linear() * rig->head_from_left->head_from_camera.linear().transpose()));
      jack.push_back({m.translation().x(), m.translation().y(), m.translation().z()});
    }
  out.mount_sd = jack.empty() ? std::vector<double>(3, 0.0) : jackknifeSds(jack);
  out.mount_sd.push_back(jackknifeAngleSd(turned));
  out.rig = std::move(*rig);
  return out;
}

void addCameraValues(registration::CalibrationRecord& r, const char* side, const registration::CameraCalibration& c) {
  const auto sd = [&](std::size_t k) { return k < c.intrinsics_sd.size() ? c.intrinsics_sd[k] : 0.0; };
  const std::string s = side;
  r.parameters.push_back({s + " fx", c.model.matrix(0, 0), "px", sd(0)});
  r.parameters.push_back({s + " fy", c.model.matrix(1, 1), "px", sd(1)});
  r.parameters.push_back({s + " cx", c.model.matrix(0, 2), "px", sd(2)});
  r.parameters.push_back({s + " cy", c.model.matrix(1, 2), "px", sd(3)});
  r.parameters.push_back({s + " k1", c.model.distortion.at<double>(0), "", sd(4)});
  r.parameters.push_back({s + " k2", c.model.distortion.at<double>(1), "", sd(5)});
  r.residuals.push_back({s + " reprojection RMS", c.rms_px, "px", 0});
}

registration::CalibrationRecord camerasRecord(const CameraOutcome& o, const acquisition::CalibrationPolicy& policy,
                                              const std::optional<registration::CameraCalibrationFile>& previous,
                                              std::vector<std::string>& drift) {
  registration::CalibrationRecord r;
  r.kind = "cameras";
  const registration::StereoCalibration& s = o.rig.stereo;
  const registration::HandEyeResult& h = *o.rig.head_from_left;
  addCameraValues(r, "left", s.left);
  addCameraValues(r, "right", s.right);
  const Eigen::Vector3d t = h.head_from_camera.translation();
  r.parameters.push_back({"stereo baseline", s.baseline_mm, "mm", s.baseline_sd_mm});
  r.parameters.push_back({"left camera mount x", t.x(), "mm", o.mount_sd[0]});
  r.parameters.push_back({"left camera mount y", t.y(), "mm", o.mount_sd[1]});
  r.parameters.push_back({"left camera mount z", t.z(), "mm", o.mount_sd[2]});
  r.parameters.push_back({"left camera mount rotation", angleDeg(h.head_from_camera.linear()), "deg", o.mount_sd[3]});
  r.residuals.push_back({"stereo reprojection RMS", s.rms_px, "px", 0});
  r.residuals.push_back({"head mount residual", h.residual_mm, "mm", 0});
  r.residuals.push_back({"head mount residual (rotation)", h.residual_deg, "deg", 0});
  r.residuals.push_back({"plate views used", static_cast<double>(s.pairs_used), "", 0});
  const double px = policy.camera_reprojection_px;
  r.checks.push_back({"reprojection RMS (left camera)", s.left.rms_px, px, "px", s.left.rms_px <= px});
  r.checks.push_back({"reprojection RMS (right camera)", s.right.rms_px, px, "px", s.right.rms_px <= px});
  r.checks.push_back({"reprojection RMS (stereo pair)", s.rms_px, px, "px", s.rms_px <= px});
  r.checks.push_back({"head mount residual (cameras)", h.residual_mm, policy.head_mount_residual_mm, "mm",
                      h.residual_mm <= policy.head_mount_residual_mm});
  if (previous) {
    const double moved = (t - previous->head_from_left.head_from_camera.translation()).norm();
    const double baseline = s.baseline_mm - previous->stereo.baseline_mm;
    r.parameters.push_back({"left camera mount change", moved, "mm", 0});
    r.parameters.push_back({"stereo baseline change", baseline, "mm", 0});
    if (moved > policy.drift_mount_mm)
      drift.push_back(format("the cameras' mount moved %.3f mm since %s (drift limit %.3f mm)", moved,
                             previous->provenance.record_id.empty() ? previous->created.c_str()
                                                                    : previous->provenance.record_id.c_str(),
                             policy.drift_mount_mm));
    if (std::abs(baseline) > policy.drift_baseline_mm)
      drift.push_back(format("the stereo baseline changed %+.3f mm (drift limit %.3f mm)", baseline, policy.drift_baseline_mm));
  }
  return r;
}

// The calibration in use of a sensor, when there is one that can be read (a damaged one is named
// in the record's notes and replaced like a missing one).
template <typename File, typename Load>
std::optional<File> inUse(const fs::path& file, Load load, std::vector<std::string>& notes) {
  if (!fs::exists(file)) return std::nullopt;
  try {
    return load(file);
  } catch (const std::exception& e) {
    notes.push_back(std::string("the calibration in use could not be read: ") + e.what());
    return std::nullopt;
  }
}

// The record's common fields, its verdict from the checks and the acceptance, and its files.
void finishRecord(registration::CalibrationRecord& r, const CalibrateJobOptions& o, const std::string& cell,
                  const std::string& trace_name, std::vector<registration::SensorIdentity> sensors,
                  const std::vector<std::string>& left_out, const std::vector<std::string>& drift) {
  const fs::path history = o.calibration_dir / "history";
  r.id = registration::newRecordId(history, r.kind);
  r.created = registration::utcNow();
  r.cell = cell;
  r.sensors = std::move(sensors);
  r.traces = {trace_name};
  const bool passed = std::all_of(r.checks.begin(), r.checks.end(), [](const RecordCheck& c) { return c.passed; });
  r.verdict = passed ? registration::RecordVerdict::Passed
                     : (o.accepted_by.empty() ? registration::RecordVerdict::Failed : registration::RecordVerdict::Accepted);
  if (r.verdict == registration::RecordVerdict::Accepted) r.accepted_by = o.accepted_by;
  r.calibration = "made on " + trace_name + "; the calibration itself is " + r.id + ".calibration.json";
  for (const std::string& l : left_out) r.notes.push_back("left out: " + l);
  for (const std::string& d : drift) r.notes.push_back("drift: " + d);
}

registration::CalibrationProvenance provenanceOf(const registration::CalibrationRecord& r) {
  return {r.id, r.cell, r.sensors, registration::toString(r.verdict), r.accepted_by};
}

bool usable(const registration::CalibrationRecord& r) { return r.verdict != registration::RecordVerdict::Failed; }

}  // namespace

std::filesystem::path calibrationFolder(const std::string& option, const acquisition::CalibrationPolicy& policy,
                                        const std::filesystem::path& runs) {
  if (!option.empty()) return option;
  if (!policy.dir.empty()) return policy.dir;
  return runs / "calibration";
}

CalibrateJobOptions cellCalibration(const acquisition::CellConfig& config, const std::filesystem::path& calibration_dir,
                                    bool digitizer, bool cameras) {
  CalibrateJobOptions calibrate;
  calibrate.run.limits = config.limits;
  calibrate.policy = config.calibration;
  calibrate.digitizer = digitizer;
  calibrate.cameras = cameras;
  calibrate.calibration_dir = calibration_dir;
  calibrate.results_database = calibrationResultsDatabase(config.results_database, calibration_dir);
  return calibrate;
}

acquisition::ScanPlan cellCalibrationPlan(const acquisition::CellConfig& config, std::uint64_t seed, bool digitizer,
                                          bool cameras) {
  return calibrationScenesOf(
      acquisition::calibrationPlan(config, acquisition::calibrationScenes(config.calibration, 1.0, seed)), digitizer,
      cameras);
}

acquisition::ScanPlan calibrationScenesOf(const acquisition::ScanPlan& plan, bool digitizer, bool cameras) {
  acquisition::ScanPlan out = plan;
  out.name = std::string("calibration of the ") + (digitizer && cameras ? "digitizer and the cameras" : digitizer ? "digitizer" : "cameras");
  std::erase_if(out.steps, [&](const acquisition::PlanStep& s) {
    if (const auto* sweep = std::get_if<acquisition::SweepStep>(&s)) return !(digitizer && sweep->scene == acquisition::Scene::ReferenceSphere);
    return !(cameras && std::get<acquisition::StereoStep>(s).scene == acquisition::Scene::CalibrationPlate);
  });
  if (out.steps.empty())
    throw std::runtime_error("the plan '" + plan.name + "' has no calibration scenes for the " +
                             (digitizer && cameras ? "digitizer or the cameras" : digitizer ? "digitizer" : "cameras"));
  return out;
}

CalibrateJob::CalibrateJob(acquisition::Cell& cell, acquisition::ScanObserver* observer)
    : cell_(cell), traced_(cell, observer) {}

CalibrateJobResult CalibrateJob::run(const CalibrateJobOptions& o) {
  if (!o.digitizer && !o.cameras) throw std::invalid_argument("CalibrateJob: no sensor to calibrate");
  for (const acquisition::PlanStep& s : o.plan.steps) {
    const auto* sweep = std::get_if<acquisition::SweepStep>(&s);
    if (sweep ? sweep->scene != acquisition::Scene::ReferenceSphere : std::get<acquisition::StereoStep>(s).scene != acquisition::Scene::CalibrationPlate)
      throw acquisition::ScanError("a calibration plan holds sphere sweeps and plate views only; '" + o.plan.name +
                                   "' has other steps");
  }
  if (o.digitizer && o.plan.sweepCount(acquisition::Scene::ReferenceSphere) == 0)
    throw acquisition::ScanError("the plan '" + o.plan.name + "' has no reference-sphere sweeps for the digitizer");
  if (o.cameras && o.plan.stereoCount(acquisition::Scene::CalibrationPlate) == 0)
    throw acquisition::ScanError("the plan '" + o.plan.name + "' has no plate views for the cameras");
  if (const auto problems = acquisition::checkPlan(o.plan, o.run.limits); !problems.empty())
    throw acquisition::ScanError("the plan cannot run on this cell: " + problems.front());

  CalibrateJobResult result;
  const fs::path history = o.calibration_dir / "history";
  fs::create_directories(history);
  result.trace_file = history / (registration::newRecordId(history, "calibration") + ".mcap");
  result.run = traced_.run(o.plan, o.run, result.trace_file);
  if (!result.run.completed)
    throw acquisition::FaultError(result.run.abort_kind, "the calibration scenes were aborted: " + result.run.abort_reason + " (the trace is " +
                             result.trace_file.string() + "; nothing was calibrated)");
  const registration::ScanTrace trace = registration::loadScanTrace(result.trace_file);
  if (!trace.session) throw std::runtime_error(result.trace_file.string() + ": no session description");
  const std::string trace_name = result.trace_file.filename().string();
  const std::string& cell = cell_.config().name;

  if (o.digitizer) {
    SensorCalibration sensor;
    std::vector<std::string> notes;
    const fs::path in_use_file = o.calibration_dir / "digitizer.json";
    const auto previous = inUse<registration::DigitizerCalibrationFile>(in_use_file, registration::loadDigitizerCalibration, notes);
    const DigitizerOutcome d = calibrateDigitizerOn(trace, o.policy);
    sensor.left_out = d.left_out;
    sensor.record = digitizerRecord(d, o.policy, previous, sensor.drift);
    finishRecord(sensor.record, o, cell, trace_name, sensorsOf(result.run, "digitizer"), sensor.left_out, sensor.drift);
    sensor.record.notes.insert(sensor.record.notes.end(), notes.begin(), notes.end());
    if (previous) sensor.previous = previous->provenance.record_id.empty() ? previous->created : previous->provenance.record_id;
    registration::DigitizerCalibrationFile file{d.fit.calibration, d.fit.rms_mm, d.fit.inliers, sensor.record.created,
                                                 "station calibrate: " + trace_name, provenanceOf(sensor.record)};
    file.calibration.clock_offset_ns = 0;  // changes at every power-up: each trace gives its own
    registration::saveDigitizerCalibration(history / (sensor.record.id + ".calibration.json"), file);
    sensor.in_use = usable(sensor.record);
    result.digitizer_file = file;
    result.digitizer = std::move(sensor);
  }
  if (o.cameras) {
    SensorCalibration sensor;
    std::vector<std::string> notes;
    const fs::path in_use_file = o.calibration_dir / "cameras.json";
    const auto previous = inUse<registration::CameraCalibrationFile>(in_use_file, registration::loadCameraCalibration, notes);
    const CameraOutcome c = calibrateCamerasOn(trace);
    sensor.left_out = c.left_out;
    sensor.record = camerasRecord(c, o.policy, previous, sensor.drift);
    finishRecord(sensor.record, o, cell, trace_name, sensorsOf(result.run, "camera"), sensor.left_out, sensor.drift);
    sensor.record.notes.insert(sensor.record.notes.end(), notes.begin(), notes.end());
    if (previous) sensor.previous = previous->provenance.record_id.empty() ? previous->created : previous->provenance.record_id;
    registration::CameraCalibrationFile file{c.rig.stereo, *c.rig.head_from_left, sensor.record.created,
                                             "station calibrate: " + trace_name, provenanceOf(sensor.record)};
    registration::saveCameraCalibration(history / (sensor.record.id + ".calibration.json"), file);
    sensor.in_use = usable(sensor.record);
    result.cameras_file = file;
    result.cameras = std::move(sensor);
  }
  // The records first (a record names what it made whether or not it is used), then the ones that
  // passed or were accepted replace theirs in use, together.
  for (auto* sensor : {&result.digitizer, &result.cameras})
    if (*sensor) {
      (*sensor)->record_file = registration::saveCalibrationRecord(history, (*sensor)->record);
      if (!o.results_database.empty() && result.history_error.empty())
        result.history_error = recordCalibrationInResults((*sensor)->record, (*sensor)->record_file, o.results_database);
    }
  registration::putCalibrationsInUse(o.calibration_dir,
                                     result.digitizer && result.digitizer->in_use ? &*result.digitizer_file : nullptr,
                                     result.cameras && result.cameras->in_use ? &*result.cameras_file : nullptr);
  return result;
}

}  // namespace stampscan::jobs
