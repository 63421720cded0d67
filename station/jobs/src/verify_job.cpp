#include "stampscan/jobs/verify_job.hpp"

#include "stampscan/jobs/calibration_results.hpp"

#include "stampscan/acquisition/calibration_plan.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/registration/measure_scan.hpp"
#include "stampscan/registration/scan_trace.hpp"

#include <algorithm>
#include <stdexcept>

namespace stampscan::jobs {

namespace fs = std::filesystem;
using registration::RecordCheck;
using registration::RecordValue;

namespace {

// The profiles of every sphere sweep, placed with `calibration`'s clock offset and latency.
std::vector<registration::Profile> allSphereProfiles(const registration::ScanTrace& trace,
                                                     const registration::HeadTrack& track,
                                                     const registration::DigitizerCalibration& calibration) {
  std::vector<registration::Profile> out;
  for (auto& sweep : registration::sphereSweepProfiles(trace, track, calibration.clock_offset_ns, calibration.latency_ns,
                                                       registration::MeasureParams{}.max_track_error_mm))
    out.insert(out.end(), sweep.begin(), sweep.end());
  return out;
}

std::vector<RecordValue> calibrationValues(const registration::DigitizerCalibration& c) {
  const Eigen::Vector3d t = c.head_from_digitizer.translation();
  const Eigen::AngleAxisd r(c.head_from_digitizer.linear());
  return {{"digitizer mount x", t.x(), "mm"},
          {"digitizer mount y", t.y(), "mm"},
          {"digitizer mount z", t.z(), "mm"},
          {"digitizer mount rotation", r.angle() * 180 / 3.14159265358979323846, "deg"},
          {"digitizer latency", static_cast<double>(c.latency_ns) * 1e-6, "ms"}};
}

}  // namespace

VerifyJobOptions cellVerification(const acquisition::CellConfig& config, const fs::path& calibration_dir) {
  VerifyJobOptions verify;
  verify.run.limits = config.limits;
  verify.sphere.form_mpe_mm = config.calibration.form_mpe_mm;
  verify.sphere.size_mpe_mm = config.calibration.size_mpe_mm;
  if (const auto& bar = config.geometry.ball_bar)
    verify.ball_bar = VerifyJobOptions::BallBar{bar->diameter_mm, bar->distance_mm, config.calibration.length_mpe_mm};
  verify.history = calibration_dir / "history";
  verify.results_database = calibrationResultsDatabase(config.results_database, calibration_dir);
  return verify;
}

acquisition::ScanPlan cellVerificationPlan(const acquisition::CellConfig& config, std::uint64_t seed,
                                           std::size_t plate_views) {
  // Every sweep calibration makes (fan position, depth, head angle, speed and direction), so that
  // the check sees what calibration saw.
  acquisition::CalibrationScenes scenes = acquisition::calibrationScenes(config.calibration, 1.0, seed);
  if (config.geometry.ball_bar) scenes.second_sphere_sweeps = config.calibration.ball_bar_sweeps;
  return verificationStepsOf(acquisition::calibrationPlan(config, scenes), plate_views);
}

acquisition::ScanPlan verificationStepsOf(const acquisition::ScanPlan& plan, std::size_t plate_views) {
  acquisition::ScanPlan out = plan;
  out.name = plate_views ? "reference sphere, ball bar and plate, verification" : "reference sphere, verification";
  std::size_t kept_views = 0;
  std::erase_if(out.steps, [&](const acquisition::PlanStep& s) {
    if (const auto* view = std::get_if<acquisition::StereoStep>(&s))
      return view->scene != acquisition::Scene::CalibrationPlate || kept_views++ >= plate_views;
    const auto& sweep = std::get<acquisition::SweepStep>(s);
    return sweep.scene != acquisition::Scene::ReferenceSphere && sweep.scene != acquisition::Scene::SecondSphere;
  });
  if (out.sweepCount(acquisition::Scene::ReferenceSphere) == 0) throw std::runtime_error("the plan '" + plan.name + "' has no reference-sphere sweeps to verify on");
  return out;
}

void verifyWithCalibration(VerifyJobOptions& options, const fs::path& file) {
  const registration::DigitizerCalibrationFile stored = registration::loadDigitizerCalibration(file);
  options.calibration = stored.calibration;
  options.calibration_source = file.string() + " (created " + stored.created + ")";
}

VerifyJob::VerifyJob(acquisition::Cell& cell, acquisition::ScanObserver* observer)
    : cell_(cell), traced_(cell, observer) {}

namespace {

// A plan that holds other steps than the verification's, or lacks what its checks need, is refused
// before anything moves.
void checkVerificationPlan(const VerifyJobOptions& o) {
  const std::size_t second_sweeps = o.plan.sweepCount(acquisition::Scene::SecondSphere);
  if (o.plan.stereoCount() != o.plan.stereoCount(acquisition::Scene::CalibrationPlate) ||
      o.plan.sweepCount() != o.plan.sweepCount(acquisition::Scene::ReferenceSphere) + second_sweeps)
    throw acquisition::ScanError("a verification plan holds sweeps over the reference sphere and the ball bar and views "
                                 "of the plate only; '" + o.plan.name + "' has other steps");
  if (o.plan.stereoCount() > 0 && !o.cameras)
    throw acquisition::ScanError("the plan has views of the plate, but no camera calibration is in use to verify");
  if (o.ball_bar && second_sweeps == 0)
    throw acquisition::ScanError("the length check needs sweeps over the ball bar's second sphere; '" + o.plan.name +
                                 "' has none");
  if (!o.run.session.reference_sphere_radius_mm)
    throw acquisition::ScanError("the cell's description gives no reference-sphere radius: nothing to verify against");
  if (const auto problems = acquisition::checkPlan(o.plan, o.run.limits); !problems.empty())
    throw acquisition::ScanError("the plan cannot run on this cell: " + problems.front());
}

// The digitizer's calibration the sweeps are measured with: the one in use, or without one, a
// calibration on these very sweeps (mount and latency); the clock offset is this trace's.
registration::DigitizerCalibration calibrationToVerify(const VerifyJobOptions& o, const registration::ScanTrace& trace,
                                                       const registration::HeadTrack& track,
                                                       const std::vector<std::pair<std::int64_t, std::int64_t>>& pairs,
                                                       double certified_diameter, VerifyJobResult& result) {
  registration::CalibrationRecord& record = result.record;
  registration::DigitizerCalibration calibration;
  if (o.calibration) {
    calibration = *o.calibration;
    record.calibration = o.calibration_source;
  } else {
    registration::SphereCalibrationParams sp;
    sp.sphere_radius = 0.5 * certified_diameter;
    sp.nominal.head_from_digitizer = trace::toIsometry(o.run.session.head_from_digitizer_nominal);
    sp.nominal.clock_offset_ns = registration::clockOffset(pairs);
    registration::DigitizerCalibration nominal = sp.nominal;
    result.calibrated = registration::calibrateDigitizer(allSphereProfiles(trace, track, nominal), track, sp);
    calibration = result.calibrated->calibration;
    record.calibration = "calibrated on these sweeps (no calibration in use): the check shows the sensor's noise and "
                         "the calibration model's fit, not a stored calibration";
    record.residuals.push_back({"calibration residual RMS", result.calibrated->rms_mm, "mm"});
  }
  calibration.clock_offset_ns = registration::clockOffset(pairs);  // changes at every power-up
  return calibration;
}

// The length check: the second sphere is located and fitted like the first, with its own certified
// diameter; the length is between the two least-squares centres.
void checkBallBar(const VerifyJobOptions& o, const registration::ScanTrace& trace, const registration::HeadTrack& track,
                  const registration::DigitizerCalibration& calibration, const registration::SphereVerificationParams& sp,
                  VerifyJobResult& result) {
  registration::CalibrationRecord& record = result.record;
  registration::SphereVerificationParams second = sp;
  second.certified_diameter_mm = o.ball_bar->second_diameter_mm;
  std::vector<registration::Profile> profiles;
  for (auto& sweep : registration::sphereSweepProfiles(trace, track, calibration.clock_offset_ns, calibration.latency_ns,
                                                       registration::MeasureParams{}.max_track_error_mm,
                                                       acquisition::Scene::SecondSphere))
    profiles.insert(profiles.end(), sweep.begin(), sweep.end());
  result.second_sphere = registration::verifySphere(registration::spherePoints(profiles, track, calibration), second);
  result.distance_mm = (result.second_sphere->fit.centre - result.digitizer.fit.centre).norm();
  result.length_error_mm = *result.distance_mm - o.ball_bar->distance_mm;
  record.parameters.push_back({"certified sphere distance", o.ball_bar->distance_mm, "mm"});
  record.parameters.push_back({"measured sphere distance", *result.distance_mm, "mm"});
  record.residuals.push_back({"second sphere radial deviation RMS", result.second_sphere->fit.rms_mm, "mm"});
  record.checks.push_back({"length measurement error E (digitizer, ball bar)", *result.length_error_mm,
                           o.ball_bar->mpe_mm, "mm", std::abs(*result.length_error_mm) <= o.ball_bar->mpe_mm});
}

// The stereo pair's check on the plate views: flatness and the lengths between its dots.
void checkStereoOnPlate(const VerifyJobOptions& o, const registration::ScanTrace& trace, VerifyJobResult& result) {
  if (!o.run.session.plate) throw std::runtime_error("the cell's description gives no calibration plate to verify on");
  registration::CalibrationRecord& record = result.record;
  const trace::PlateRecord& plate = *o.run.session.plate;
  std::vector<cv::Mat> left, right;
  for (std::size_t i = 0; i < trace.plate_left.size() && i < trace.plate_right.size(); ++i) {
    left.push_back(trace.plate_left[i].image);
    right.push_back(trace.plate_right[i].image);
  }
  result.stereo = registration::verifyStereoOnPlate(left, right, o.cameras->stereo,
                                                    {plate.columns, plate.rows, plate.pitch_mm}, o.stereo);
  const registration::StereoPlateCheck& s = *result.stereo;
  record.parameters.push_back({"plate length checked (longest)", s.longest_length_mm, "mm"});
  record.residuals.push_back({"plate length error RMS (stereo pair)", s.rms_length_error_mm, "mm"});
  record.residuals.push_back({"plate views (stereo pair)", static_cast<double>(s.views), ""});
  record.checks.push_back({"flat form error F[Form.Pla] (stereo pair, plate)", s.form_error_mm, o.stereo.form_mpe_mm,
                           "mm", s.form_passed});
  record.checks.push_back({"length measurement error E (stereo pair, plate dots)", s.length_error_mm,
                           o.stereo.length_mpe_mm, "mm", s.length_passed});
}

}  // namespace

VerifyJobResult VerifyJob::run(const VerifyJobOptions& o) {
  checkVerificationPlan(o);
  VerifyJobResult result;
  registration::CalibrationRecord& record = result.record;
  record.kind = "verification";
  record.id = registration::newRecordId(o.history, record.kind);
  record.created = registration::utcNow();
  record.cell = cell_.config().name;
  fs::create_directories(o.history);
  result.trace_file = o.history / (record.id + ".mcap");
  record.traces.push_back(result.trace_file.filename().string());
  result.run = traced_.run(o.plan, o.run, result.trace_file);
  for (const auto& d : result.run.devices) record.sensors.push_back({d.family, d.model, d.serial, d.firmware});
  if (!result.run.completed)
    throw acquisition::FaultError(result.run.abort_kind, "the verification sweeps were aborted: " + result.run.abort_reason + " (the trace is " +
                             result.trace_file.string() + "; no record was written)");

  const registration::ScanTrace trace = registration::loadScanTrace(result.trace_file);
  const auto pairs = trace.clock_pairs.find("digitizer");
  if (pairs == trace.clock_pairs.end())
    throw std::runtime_error(result.trace_file.string() + ": no clock-sync pairs for the digitizer");
  const registration::HeadTrack track(trace.head);
  const double certified_diameter = 2 * *o.run.session.reference_sphere_radius_mm;
  const registration::DigitizerCalibration calibration =
      calibrationToVerify(o, trace, track, pairs->second, certified_diameter, result);

  // The reference sphere: ISO 10360-8's probing form and size errors.
  const std::vector<registration::Vec3> points =
      registration::spherePoints(allSphereProfiles(trace, track, calibration), track, calibration);
  registration::SphereVerificationParams sp = o.sphere;
  sp.certified_diameter_mm = certified_diameter;
  result.digitizer = registration::verifySphere(points, sp);
  const registration::SphereVerification& v = result.digitizer;
  record.parameters = calibrationValues(calibration);
  record.parameters.push_back({"certified sphere diameter", certified_diameter, "mm"});
  record.parameters.push_back({"fitted sphere diameter", 2 * v.fit.radius, "mm"});
  record.parameters.push_back({"sphere centre x", v.fit.centre.x(), "mm"});
  record.parameters.push_back({"sphere centre y", v.fit.centre.y(), "mm"});
  record.parameters.push_back({"sphere centre z", v.fit.centre.z(), "mm"});
  record.residuals.push_back({"radial deviation RMS", v.fit.rms_mm, "mm"});
  record.residuals.push_back({"points on the sphere", static_cast<double>(v.points_on_sphere), ""});
  record.residuals.push_back({"points measured", static_cast<double>(v.points_measured), ""});
  record.checks.push_back({"probing form error P[Form.Sph.All] (digitizer)", v.form_error_mm, sp.form_mpe_mm, "mm", v.form_passed});
  record.checks.push_back({"probing size error P[Size.Sph.All] (digitizer)", v.size_error_mm, sp.size_mpe_mm, "mm", v.size_passed});
  if (o.ball_bar) checkBallBar(o, trace, track, calibration, sp, result);
  else record.notes.push_back("no length check: the cell gives no ball bar ([ball_bar] in the cell file)");
  if (o.cameras && !trace.plate_left.empty()) checkStereoOnPlate(o, trace, result);
  else record.notes.push_back("no stereo check: no camera calibration in use, or no plate views in the plan");

  const bool all_passed =
      std::all_of(record.checks.begin(), record.checks.end(), [](const RecordCheck& c) { return c.passed; });
  record.verdict = all_passed ? registration::RecordVerdict::Passed : registration::RecordVerdict::Failed;
  if (result.run.lost_profiles > 0)
    record.notes.push_back(std::to_string(result.run.lost_profiles) + " digitizer profiles were lost during the sweeps");
  result.record_file = registration::saveCalibrationRecord(o.history, record);
  if (!o.results_database.empty())
    result.history_error = recordCalibrationInResults(record, result.record_file, o.results_database);
  return result;
}

}  // namespace stampscan::jobs
