#include "stampscan/jobs/scan_job.hpp"

#include "stampscan/acquisition/trace/mcap_writer.hpp"
#include "stampscan/acquisition/trace/trace_recorder.hpp"
#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/results/run_recording.hpp"
#include "stampscan/run_folder/folder_name.hpp"
#include "stampscan/run_folder/run_record.hpp"
#include "stampscan/jobs/fit_runner.hpp"
#include "live_measurement.hpp"


#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <functional>
#include <limits>

namespace stampscan::jobs {

namespace fs = std::filesystem;

namespace {

// A fresh folder under `runs`: two scans of one part within a second get "-2", "-3", ...
fs::path newRunFolder(const fs::path& runs, const std::string& part_id) {
  fs::create_directories(runs);
  const std::string base = run_folder::runFolderName(part_id, std::time(nullptr));
  for (int k = 1;; ++k) {
    const fs::path dir = runs / (k == 1 ? base : base + "-" + std::to_string(k));
    if (fs::create_directory(dir)) return dir;
  }
}

run_folder::RunRecord runRecord(const ScanJobOptions& o, const acquisition::Cell& cell, const acquisition::ScanRunResult& r) {
  run_folder::RunRecord run;
  run.part_id = o.part_id;
  run.plan = o.plan.name;
  run.cell = cell.config().name;
  run.completed = r.completed;
  run_folder::ScanFigures& s = run.scan.emplace();
  s.sweeps = static_cast<std::int64_t>(r.sweeps_done);
  s.wall_seconds = r.wall_seconds;
  s.motion_seconds = r.motion_seconds;
  s.profiles = static_cast<std::int64_t>(r.profiles);
  s.lost_profiles = static_cast<std::int64_t>(r.lost_profiles);
  s.sweeps_repeated = static_cast<std::int64_t>(r.sweeps_repeated);
  s.sweeps_over_loss_limit = static_cast<std::int64_t>(r.sweeps_over_loss_limit);
  s.stereo_views = static_cast<std::int64_t>(r.views_done);
  s.stereo_views_missing = static_cast<std::int64_t>(r.views_missing);
  s.positions = static_cast<std::int64_t>(r.positions);
  s.spent_seconds = {.moving = r.spent.moving,
                     .settling = r.spent.settling,
                     .waiting_for_frames = r.spent.frames,
                     .clock_sync = r.spent.clock_sync,
                     .digitizer_start_drain_stop = r.spent.digitizer,
                     .other = r.spent.other};
  for (const auto& d : r.devices) run.devices.push_back({d.family, d.model, d.serial, d.firmware});
  if (!r.completed) run.abort_reason = r.abort_reason;
  run.started_by = o.started_by;
  run.safety_events = r.safety_events;
  // The cloud, the surface and the maps are in the machine frame; the part's datum frame (its nominal
  // model's) is here on the table.
  const acquisition::Fixture& fixture = cell.config().geometry.fixture;
  run.fixture.name = fixture.name;
  for (int k = 0; k < 3; ++k) {
    run.fixture.datum_mm[k] = fixture.datum.position_mm[k];
    run.fixture.datum_rotation_deg[k] = fixture.datum.rotation_deg[k];
  }
  return run;
}

// run.json's "measurement": what was measured and how fast, one measurement's uncertainty per path.
run_folder::MeasurementFigures measurementRecord(const ScanJobResult& result, const registration::ScanMeasurement& m,
                                                 const std::optional<run_folder::SurfaceFigures>& surface) {
  run_folder::MeasurementFigures record;
  record.elements = static_cast<std::int64_t>(result.elements);
  record.seconds_after_scan = result.measure_seconds;
  record.cloud4d_seconds_after_scan = result.cloud4d_seconds;
  record.digitizer_latency_ms = static_cast<double>(m.digitizer.latency_ns) * 1e-6;
  record.measurements = static_cast<std::int64_t>(m.elements.size());
  // One measurement's standard uncertainty per sensor path, and its part shared by the path's
  // measurements of one element (registration/element_merge.hpp), as this scan's twins showed them.
  const auto noise = [](const registration::PathNoise& p) -> std::optional<run_folder::PathUncertainty> {
    if (!p.strain) return std::nullopt;
    return run_folder::PathUncertainty{.strain = *p.strain,
                                       .strain_shared = p.strain_shared,
                                       .position_mm = p.position_mm.value_or(0.0),
                                       .position_shared_mm = p.position_shared_mm,
                                       .twin_pairs = static_cast<std::int64_t>(p.twin_pairs)};
  };
  record.laser_uncertainty = noise(m.merged.laser);
  record.stereo_uncertainty = noise(m.merged.stereo);
  if (m.sphere) record.sphere_residual_mm = m.sphere->rms_mm;
  record.surface = surface;
  return record;
}

// run.json's "accuracy": the scan against the simulator's truth (a virtual cell).
run_folder::AccuracyFigures accuracyRecord(const ScanJobResult& result, const SimulationTruth& truth) {
  const ScanAccuracy& a = *result.accuracy;
  run_folder::AccuracyFigures record;
  record.matched = static_cast<std::int64_t>(a.matched);
  record.position_rms_mm = a.position_rms_mm;
  record.strain_rms = a.strain_rms;
  record.strain_within_expanded_uncertainty = a.within_expanded_uncertainty;
  record.true_latency_ms = static_cast<double>(truth.digitizer_latency_ns) * 1e-6;
  if (!truth.visible.empty())
    record.visible = run_folder::VisibleFigures{.elements = static_cast<std::int64_t>(a.visible),
                                                .found = static_cast<std::int64_t>(a.visible_found),
                                                .found_not_visible = static_cast<std::int64_t>(a.found_not_visible)};
  record.surface_strain = result.surface_accuracy;
  if (a.laser.matched) record.laser_led = a.laser;
  if (a.stereo.matched) record.stereo_led = a.stereo;
  return record;
}

// A replay's check: the recording measured as `station process` measures it must give the same
// measurements. (Compared measurement by measurement: a sweep's end that the replay measures one
// element less would shift a merged element by half its twins' distance.) Fills the result's
// figures and returns run.json's "replay".
run_folder::ReplayFigures compareWithRecording(const fs::path& recording, const registration::MeasureParams& measure,
                                    const registration::ScanMeasurement& m, ScanJobResult& result) {
  const registration::ScanTrace recorded = registration::loadScanTrace(recording, {}, measure.with_stereo);
  const fitting::Cloud reference = registration::toCloud(registration::measureScan(recorded, measure, nullptr).elements);
  result.recording_measurements = reference.size();
  result.against_recording = accuracyAgainst(registration::toCloud(m.elements), reference);
  return {.recording = recording.string(),
          .reference_measurements = static_cast<std::int64_t>(reference.size()),
          .matched = static_cast<std::int64_t>(result.against_recording->matched),
          .position_rms_mm = result.against_recording->position_rms_mm,
          .strain_rms = result.against_recording->strain_rms};
}

// The runner's messages to the recorder (the file) and to the live trace (the measuring thread).
class TeeSink final : public trace::TraceSink {
 public:
  TeeSink(trace::TraceSink& a, trace::TraceSink& b) : a_(a), b_(b) {}
  void message(std::string_view topic, std::int64_t log_time_ns, std::vector<std::byte> bytes) override {
    b_.message(topic, log_time_ns, bytes);
    a_.message(topic, log_time_ns, std::move(bytes));
  }
  void metadata(const std::string& name, const std::map<std::string, std::string>& values) override {
    a_.metadata(name, values);
    b_.metadata(name, values);
  }

 private:
  trace::TraceSink& a_;
  trace::TraceSink& b_;
};

// The job's observer as the runner (its thread) and the live measurement (its own) see it: calls
// are forwarded one at a time, and the runner's progress tells the measurement which steps are done.
class SerialObserver final : public ScanJobObserver {
 public:
  explicit SerialObserver(ScanJobObserver* to) : to_(to) {}
  void measuring(LiveMeasurement* live) { live_ = live; }
  void checkPassed(const std::string& what) override {
    std::lock_guard lock(mutex_);
    if (to_) to_->checkPassed(what);
  }
  void progress(const acquisition::ScanProgress& p) override {
    if (live_) live_->stepsDone(p.step);
    std::lock_guard lock(mutex_);
    if (to_) to_->progress(p);
  }
  void safetyEvent(acquisition::FaultKind kind, const std::string& what) override {
    std::lock_guard lock(mutex_);
    if (to_) to_->safetyEvent(kind, what);
  }
  void stageDone(std::string_view stage, const std::string& text) override {
    std::lock_guard lock(mutex_);
    if (to_) to_->stageDone(stage, text);
  }
  void elementsMeasured(std::string_view stage, const std::vector<registration::GridElement>& elements) override {
    std::lock_guard lock(mutex_);
    if (to_) to_->elementsMeasured(stage, elements);
  }

 private:
  ScanJobObserver* to_;
  LiveMeasurement* live_ = nullptr;
  std::mutex mutex_;
};

// Records the run folder in the results database of its runs folder; returns what went wrong, or
// nothing. A history that cannot be written never loses the run itself: its folder is complete.
std::string recordInHistory(const fs::path& run_dir, const std::string& database, const std::string& failure) {
  try {
    results::recordRunInResults(run_dir, database, failure);
    return {};
  } catch (const std::exception& e) {
    return e.what();
  }
}

// The stored calibrations a plan needs (the sensors it does not calibrate itself), loaded and
// checked against the cell before anything moves; and the measuring parameters that use them.
struct CalibrationInUse {
  std::optional<registration::DigitizerCalibrationFile> digitizer;
  std::optional<registration::CameraCalibrationFile> cameras;
  fs::path digitizer_file, cameras_file;
  std::string digitizer_text = "calibrated on this scan's reference-sphere sweeps";
  std::string cameras_text = "none: the plan has no stereo views";
};

template <typename File, typename Load>
File loadInUse(const fs::path& file, const char* sensor, Load load) {
  const std::string fix = std::string("run `station calibrate ") + sensor + "`";
  if (!fs::exists(file))
    throw acquisition::ScanError("no " + std::string(sensor) + " calibration in use: " + file.string() +
                                 " does not exist, and the plan does not calibrate the " + sensor + " itself; " + fix);
  try {
    return load(file);
  } catch (const std::exception& e) {
    throw acquisition::ScanError(std::string(e.what()) + "; " + fix);
  }
}

CalibrationInUse calibrationFor(const ScanJobOptions& o, registration::MeasureParams& measure) {
  CalibrationInUse in_use;
  if (o.plan.sweepCount(acquisition::Scene::ReferenceSphere) == 0) {
    in_use.digitizer_file = o.calibration_dir / "digitizer.json";
    in_use.digitizer = loadInUse<registration::DigitizerCalibrationFile>(in_use.digitizer_file, "digitizer",
                                                                         registration::loadDigitizerCalibration);
    measure.digitizer = in_use.digitizer->calibration;
    in_use.digitizer_text = in_use.digitizer_file.string() + " (record " + in_use.digitizer->provenance.record_id +
                            ", created " + in_use.digitizer->created + ")";
  }
  const bool part_views = o.plan.stereoCount(acquisition::Scene::Part) > 0;
  const bool plate_views = o.plan.stereoCount(acquisition::Scene::CalibrationPlate) >= measure.min_plate_views;
  if (part_views && plate_views) in_use.cameras_text = "calibrated on this scan's plate views";
  if (part_views && !plate_views) {
    in_use.cameras_file = o.calibration_dir / "cameras.json";
    in_use.cameras = loadInUse<registration::CameraCalibrationFile>(in_use.cameras_file, "cameras",
                                                                    registration::loadCameraCalibration);
    // The cameras' intrinsics hold for the image size they were calibrated at only.
    const cv::Size calibrated = in_use.cameras->stereo.left.model.size;
    if (const auto& nominal = o.run.session.camera_nominal;
        nominal && (nominal->width != calibrated.width || nominal->height != calibrated.height))
      throw acquisition::ScanError(in_use.cameras_file.string() + " was calibrated on " + std::to_string(calibrated.width) +
                                   " x " + std::to_string(calibrated.height) + " images, but this scan takes " +
                                   std::to_string(nominal->width) + " x " + std::to_string(nominal->height) +
                                   "; calibrate the cameras at the scan's resolution, or scan without stereo views");
    measure.cameras = in_use.cameras;
    in_use.cameras_text = in_use.cameras_file.string() + " (record " + in_use.cameras->provenance.record_id +
                          ", created " + in_use.cameras->created + ")";
  }
  measure.with_stereo = part_views && (plate_views || measure.cameras);
  return in_use;
}

// The stored calibrations against the sensors that answer: throws ScanError naming the file and
// what does not match (before motion: nothing has moved).
void checkAgainstSensors(const CalibrationInUse& in_use, const std::string& cell, const acquisition::CalibrationPolicy& policy,
                         const std::vector<drivers::DeviceIdentity>& devices) {
  registration::CalibrationExpectation expected;
  expected.cell = cell;
  expected.validity_days = policy.validity_days;
  for (const auto& d : devices) expected.sensors.push_back({d.family, d.model, d.serial, d.firmware});
  const auto check = [&](const fs::path& file, const std::string& created, const registration::CalibrationProvenance& p,
                         const char* sensor) {
    if (const auto problem = registration::calibrationProblem(file, created, p, expected))
      throw acquisition::ScanError("the " + std::string(sensor) + " calibration cannot be used: " + *problem +
                                   "; run `station calibrate " + sensor + "`");
  };
  if (in_use.digitizer) check(in_use.digitizer_file, in_use.digitizer->created, in_use.digitizer->provenance, "digitizer");
  if (in_use.cameras) check(in_use.cameras_file, in_use.cameras->created, in_use.cameras->provenance, "cameras");
}

// The surface: the elements' strain on the shape fitted to the laser's returns, written as
// fitted.ply and mesh.ply, and the Cloud4D again with the surface's strain at each element beside
// the element's own. Without a shape (a plan without part sweeps) the surface of the elements
// alone. Returns run.json's "measurement.surface" (nothing for the elements' own surface).
std::optional<run_folder::SurfaceFigures> writeSurface(const fitting::ShapeSurface* shape, const SimulationTruth* truth, const fitting::PlyWriteOptions& w,
                            fitting::Cloud& cloud, ScanJobResult& result, ScanJobObserver& observer) {
  if (shape == nullptr) {
    FitOutcome fit = runFit(cloud, fitting::FitParams{}, FitRun{.with_mesh = true});
    colorByStrain(fit.surface);
    colorByStrain(fit.mesh.vertices);
    fitting::writePly(result.run_dir / "fitted.ply", fit.surface, w);
    fitting::writePly(result.run_dir / "mesh.ply", fit.mesh, w);
    return std::nullopt;
  }
  const fitting::ShapeAndStrain fit = runStrainOnShape(*shape, cloud);
  fitting::writePly(result.run_dir / "fitted.ply", fit.surface, w);
  fitting::writePly(result.run_dir / "mesh.ply", fit.mesh, w);
  cloud.scalars[fitting::kFittedStrain] = fit.strain_at_carriers;
  fitting::writePly(result.run_dir / "cloud4d.ply", cloud, w);
  if (truth) result.surface_accuracy = surfaceAccuracyAgainst(cloud, fit.surface, *truth);
  observer.stageDone("surface", std::to_string(fit.surface.size()) + " points, " +
                                    std::to_string(fit.mesh.triangles.size()) + " triangles");
  return run_folder::SurfaceFigures{.laser_returns = static_cast<std::int64_t>(fit.shape_points),
                                    .points = static_cast<std::int64_t>(fit.surface.size()),
                                    .points_without_strain = static_cast<std::int64_t>(fit.without_strain),
                                    .mesh_triangles = static_cast<std::int64_t>(fit.mesh.triangles.size()),
                                    .shape_bandwidth_median_mm = fit.shape_stats.bandwidth.median,
                                    .strain_bandwidth_median_mm = fit.strain_bandwidth.median,
                                    .seconds = fit.seconds};
}

fitting::PlyWriteOptions plyOptions(const std::string& part_id) {
  fitting::PlyWriteOptions w;
  w.comment = "StampScan Cloud4D, part " + part_id;
  return w;
}

// The Cloud4D: one point per printed element (its measurements by every sweep and view merged);
// every measurement beside it.
fitting::Cloud writeElements(const registration::ScanMeasurement& m, const std::string& part_id, const fs::path& run_dir) {
  fitting::Cloud cloud = registration::toCloud(m.merged.elements);
  fitting::writePly(run_dir / "cloud4d.ply", cloud, plyOptions(part_id));
  fitting::PlyWriteOptions wm;
  wm.comment = "StampScan measurements of the grid elements, part " + part_id;
  fitting::writePly(run_dir / "measurements.ply", registration::toCloud(m.elements), wm);
  return cloud;
}

}  // namespace

ScanAccuracy accuracyAgainst(const fitting::Cloud& measured, const fitting::Cloud& truth,
                             const std::vector<std::uint8_t>& visible) {
  ScanAccuracy a;
  if (truth.size() == 0 || !measured.hasStrain() || !truth.hasStrain()) return a;
  const fitting::KdTree tree(truth.positions);
  std::vector<fitting::Neighbor> nn;
  double sp = 0, ss = 0;
  const auto stated = measured.scalars.find(fitting::kStrainUncertainty);
  const bool states = stated != measured.scalars.end() && stated->second.size() == measured.size();
  const auto source = measured.scalars.find(fitting::kSource);
  const bool sourced = source != measured.scalars.end() && source->second.size() == measured.size();
  run_folder::SensorAccuracyFigures* sensor[2] = {&a.laser, &a.stereo};
  double sensor_position_sq[2] = {0, 0}, sensor_strain_sq[2] = {0, 0};  // laser, stereo
  std::size_t covered = 0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    tree.knn(measured.positions[i], 1, nn);
    if (nn.empty() || nn[0].distance_sq > 0.5 * 0.5) continue;
    ++a.matched;
    sp += nn[0].distance_sq;
    const double d = measured.strain[i] - truth.strain[nn[0].index];
    ss += d * d;
    if (sourced) {
      const int k = source->second[i] == static_cast<double>(registration::Source::Stereo) ? 1 : 0;
      ++sensor[k]->matched;
      sensor_position_sq[k] += nn[0].distance_sq;
      sensor_strain_sq[k] += d * d;
    }
    if (states && std::isfinite(stated->second[i]) && stated->second[i] > 0) {
      ++a.with_uncertainty;
      covered += std::abs(d) <= 2 * stated->second[i];
    }
  }
  if (a.with_uncertainty) a.within_expanded_uncertainty = static_cast<double>(covered) / static_cast<double>(a.with_uncertainty);
  if (a.matched) {
    a.position_rms_mm = std::sqrt(sp / static_cast<double>(a.matched));
    a.strain_rms = std::sqrt(ss / static_cast<double>(a.matched));
  }
  for (int k = 0; k < 2; ++k)
    if (const auto n = static_cast<double>(sensor[k]->matched); n > 0) {
      sensor[k]->position_rms_mm = std::sqrt(sensor_position_sq[k] / n);
      sensor[k]->strain_rms = std::sqrt(sensor_strain_sq[k] / n);
    }
  if (visible.size() == truth.size() && measured.size() > 0) {
    const fitting::KdTree found(measured.positions);
    for (std::size_t i = 0; i < truth.size(); ++i) {
      found.knn(truth.positions[i], 1, nn);
      const bool is_found = !nn.empty() && nn[0].distance_sq <= 0.5 * 0.5;
      if (visible[i]) {
        ++a.visible;
        if (is_found) ++a.visible_found;
      } else if (is_found) {
        ++a.found_not_visible;
      }
    }
  }
  return a;
}

run_folder::SurfaceStrainFigures surfaceAccuracyAgainst(const fitting::Cloud& elements, const fitting::Cloud& surface,
                                                        const SimulationTruth& truth) {
  run_folder::SurfaceStrainFigures a;
  const fitting::Cloud& t = truth.elements;
  const auto fitted = elements.scalars.find(fitting::kFittedStrain);
  if (t.size() < 2 || elements.empty() || !elements.hasStrain() || !t.hasStrain() || fitted == elements.scalars.end() ||
      fitted->second.size() != elements.size() || surface.strain.size() != surface.size())
    return a;
  constexpr double kMatch = 0.5;  // mm, as accuracyAgainst
  const fitting::KdTree true_tree(t.positions), found_tree(elements.positions);
  std::vector<fitting::Neighbor> nn;
  double own = 0, on_surface = 0;
  for (std::size_t i = 0; i < elements.size(); ++i) {
    if (!std::isfinite(fitted->second[i]) || !std::isfinite(elements.strain[i])) continue;
    true_tree.knn(elements.positions[i], 1, nn);
    if (nn.empty() || nn[0].distance_sq > kMatch * kMatch) continue;
    ++a.elements;
    own += std::pow(elements.strain[i] - t.strain[nn[0].index], 2);
    on_surface += std::pow(fitted->second[i] - t.strain[nn[0].index], 2);
  }
  if (a.elements) {
    a.at_elements_rms = std::sqrt(on_surface / static_cast<double>(a.elements));
    a.elements_own_rms = std::sqrt(own / static_cast<double>(a.elements));
  }
  // The pitch: the true elements' median nearest-neighbour distance.
  std::vector<double> nearest;
  for (std::size_t i = 0; i < t.size(); i += std::max<std::size_t>(1, t.size() / 500)) {
    true_tree.knn(t.positions[i], 2, nn);
    if (nn.size() == 2) nearest.push_back(std::sqrt(nn[1].distance_sq));
  }
  std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2), nearest.end());
  const double pitch = nearest[nearest.size() / 2];
  std::vector<fitting::Neighbor> f;
  const auto found = [&](std::size_t true_index) {
    found_tree.knn(t.positions[true_index], 1, f);
    return !f.empty() && f[0].distance_sq <= kMatch * kMatch;
  };
  double between = 0;
  for (std::size_t i = 0; i < surface.size(); ++i) {
    true_tree.knn(surface.positions[i], 2, nn);
    if (nn.size() < 2 || !found(nn[0].index)) continue;
    const double d = std::sqrt(nn[0].distance_sq);
    if (d > pitch) continue;
    ++a.within_grid_points;
    const double s = surface.strain[i];
    if (!std::isfinite(s)) {
      ++a.within_grid_without_strain;
      continue;
    }
    if (!truth.thickness_strain_at || d < 0.4 * pitch || d > 0.6 * pitch || !found(nn[1].index)) continue;
    ++a.between_points;
    between += std::pow(s - truth.thickness_strain_at(surface.positions[i]), 2);
  }
  if (a.between_points) a.between_rms = std::sqrt(between / static_cast<double>(a.between_points));
  return a;
}

namespace {

// run.json's figures of a measured run: the measurement, the accuracy on a virtual cell, the
// replay's check, what the run lacks, and what it was given.
void completeRecord(const ScanJobOptions& o, const registration::ScanMeasurement& m, const fitting::Cloud& cloud,
                    const std::optional<run_folder::SurfaceFigures>& surface, const registration::MeasureParams& measure,
                    ScanJobResult& result, ScanJobObserver& observer, run_folder::RunRecord& record) {
  result.elements = cloud.size();
  result.measurements = m.elements.size();
  result.digitizer = m.digitizer;
  if (m.sphere) result.sphere_residual_mm = m.sphere->rms_mm;
  record.measurement = measurementRecord(result, m, surface);
  if (o.truth) {
    result.accuracy = accuracyAgainst(cloud, o.truth->elements, o.truth->visible);
    record.accuracy = accuracyRecord(result, *o.truth);
  }
  if (!o.replayed_trace.empty()) record.replay = compareWithRecording(o.replayed_trace, measure, m, result);
  result.data_loss = dataLoss(result.run);
  // Data that arrived whole but measured much less than the plan predicts is as damaged a result.
  if (const auto shortfall = measurementShortfall(o.plan, m.elements)) {
    observer.stageDone("elements", "short of the plan: " + *shortfall);
    result.data_loss = result.data_loss ? *result.data_loss + "; " + *shortfall : *shortfall;
  }
  record.data_loss = result.data_loss.value_or("");
  record.material = o.material;
  record.program = o.program;
  if (o.part_program) record.part_program = run_folder::PartProgramUsed{o.part_program->name, o.part_program->folder};
}

// The report of what was measured: the verdict, the maps, the FLD, the PDF. A report that fails
// leaves the measured run as it is and says why.
void writeReport(const ScanJobOptions& o, ScanJobResult& result) {
  try {
    report::ReportOptions options;
    options.material = o.material;
    options.program = o.program;
    options.materials = o.materials;
    result.report = report::writeRunReport(result.run_dir, options);
  } catch (const std::exception& e) {
    result.report_error = e.what();
  }
}

}  // namespace

ScanJob::ScanJob(acquisition::Cell& cell, ScanJobObserver* observer) : cell_(cell), observer_(observer) {}

void ScanJob::abort(const std::string& reason) {
  std::lock_guard lock(mutex_);
  if (runner_) {
    runner_->abort(reason);
    return;
  }
  if (!pending_abort_) pending_abort_ = reason;
  if (live_) live_->cancel();  // after the motion: the measurement stops at its next step
}

ScanJobResult ScanJob::run(const ScanJobOptions& o) {
  ScanJobResult result;
  // Refuse a plan that cannot run before a folder is made for it.
  const auto problems = acquisition::checkPlan(o.plan, o.run.limits);
  if (!problems.empty()) throw acquisition::ScanError("the plan cannot run on this cell: " + problems.front());
  // The stereo views are measured when the plan has views of the part and the cameras are
  // calibrated: on the plan's plate views, or by the stored calibration.
  registration::MeasureParams measure;
  // The fitted surface takes its shape from every laser return (fitting/shape_and_strain.hpp).
  measure.keep_surface_points = true;
  const CalibrationInUse in_use = calibrationFor(o, measure);
  result.digitizer_calibration = in_use.digitizer_text;
  result.camera_calibration = in_use.cameras_text;
  const std::string database = o.results_database.empty() ? o.runs_dir.string() : o.results_database;
  result.run_dir = newRunFolder(o.runs_dir, o.part_id);
  if (observer_) observer_->runFolder(result.run_dir);
  SerialObserver observer(observer_);
  acquisition::ScanRunParams run_params = o.run;
  run_params.before_motion = [&, previous = o.run.before_motion](const std::vector<drivers::DeviceIdentity>& devices) {
    if (previous) previous(devices);
    checkAgainstSensors(in_use, cell_.config().name, o.calibration_policy, devices);
    if (in_use.digitizer || in_use.cameras)
      observer.checkPassed("calibration in use: made on this cell with these sensors, within its validity");
  };

  // The scan, measured as it is recorded (the live measurement, on its own thread).
  registration::LiveScanTrace live(measure.with_stereo);
  std::optional<LiveMeasurement> measuring;
  measuring.emplace(live, o.plan, measure, &observer);
  observer.measuring(&*measuring);
  // The measurement is the job's to stop until it is dropped (every way out of this function).
  const auto forget_measuring = [&] {
    std::lock_guard lock(mutex_);
    live_ = nullptr;
  };
  {
    std::lock_guard lock(mutex_);
    live_ = &*measuring;
  }
  struct Forget {
    std::function<void()> f;
    ~Forget() { f(); }
  } forget{forget_measuring};
  const fs::path trace_file = result.run_dir / "trace.mcap";
  try {
    result.run = runOnCell(o.plan, run_params, live, observer, trace_file);
  } catch (const acquisition::ScanError&) {
    observer.measuring(nullptr);
    forget_measuring();
    measuring.reset();
    std::error_code ignored;
    fs::remove_all(result.run_dir, ignored);  // nothing moved: no run to keep
    throw;
  }
  observer.measuring(nullptr);
  if (observer_) observer_->scanDone(result.run);
  run_folder::RunRecord record = runRecord(o, cell_, result.run);
  record.calibration = run_folder::CalibrationUsed{result.digitizer_calibration, result.camera_calibration};
  if (!result.run.completed) {
    forget_measuring();
    measuring.reset();
    run_folder::writeRunRecord(result.run_dir, record);
    recordInHistory(result.run_dir, database, "");  // as aborted, with its reason from run.json
    throw ScanStopped(result.run.abort_kind, "the scan was aborted: " + result.run.abort_reason + " (the trace up to there is in " +
                      trace_file.string() + ")");
  }

  // What the live measurement has not done yet, then the fit.
  const auto t0 = std::chrono::steady_clock::now();
  // A stop after the motion (Ctrl-C, SIGTERM, the panel's abort): the trace and what was measured
  // are kept, and the run is recorded as incomplete; `station process` measures it again.
  const auto stopped = [&](const char* during) {
    std::optional<std::string> reason;
    {
      std::lock_guard lock(mutex_);
      reason = pending_abort_;
    }
    if (!reason) return;
    forget_measuring();
    measuring.reset();
    record.completed = false;
    record.abort_reason = *reason + " " + during;
    run_folder::writeRunRecord(result.run_dir, record);
    recordInHistory(result.run_dir, database, "");
    throw ScanStopped(acquisition::FaultKind::StopRequested, "the scan was stopped " + std::string(during) + ": " + *reason + " (its trace" +
                      (fs::exists(result.run_dir / "cloud4d.ply") ? " and elements are" : " is") + " kept in " +
                      result.run_dir.string() + "; `station process --with-stereo --fit` measures it again)");
  };
  const registration::ScanMeasurement m = measuring->finish();
  fitting::Cloud cloud = writeElements(m, o.part_id, result.run_dir);
  result.cloud4d_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stopped("after its motion, while measuring");
  // The surface: its shape from the laser's returns (fitted since the last part sweep), the
  // elements' strain on it.
  std::unique_ptr<fitting::ShapeSurface> shape = measuring->shape();
  stopped("while its surface was fitted");
  forget_measuring();
  measuring.reset();
  const std::optional<run_folder::SurfaceFigures> surface =
      writeSurface(shape.get(), o.truth ? &*o.truth : nullptr, plyOptions(o.part_id), cloud, result, observer);
  shape.reset();  // the fit's every return and its trees: the report needs none of it
  result.measure_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  completeRecord(o, m, cloud, surface, measure, result, observer, record);
  run_folder::writeRunRecord(result.run_dir, record);
  writeReport(o, result);
  // Every run is a row of the results history, a failed report included (as failed, with why).
  result.history_error = recordInHistory(result.run_dir, database, result.report_error);
  return result;
}

acquisition::ScanRunResult ScanJob::runOnCell(const acquisition::ScanPlan& plan, const acquisition::ScanRunParams& params,
                                              trace::TraceSink& live, acquisition::ScanObserver& observer,
                                              const fs::path& trace_file) {
  trace::McapWriter writer(trace_file);
  trace::TraceRecorder recorder(writer);
  TeeSink tee(recorder, live);
  const acquisition::StationClock clock;
  acquisition::ScanRunner runner(cell_.devices(), tee, clock, &observer);
  {
    std::lock_guard lock(mutex_);
    runner_ = &runner;
    if (pending_abort_) runner.abort(*pending_abort_);
  }
  struct Forget {
    ScanJob& job;
    ~Forget() {
      std::lock_guard lock(job.mutex_);
      job.runner_ = nullptr;
    }
  } forget{*this};
  acquisition::ScanRunResult result = runner.run(plan, params);
  writer.close();
  return result;
}

std::optional<std::string> dataLoss(const acquisition::ScanRunResult& r) {
  std::string text;
  const auto add = [&text](const std::string& part) { text += (text.empty() ? "" : "; ") + part; };
  if (r.views_missing > 0) add(std::to_string(r.views_missing) + " stereo views missing (no frames from a camera)");
  if (r.sweeps_over_loss_limit > 0)
    add(std::to_string(r.sweeps_over_loss_limit) + " sweeps lost more digitizer profiles than allowed even when repeated");
  if (text.empty()) return std::nullopt;
  return text;
}

std::optional<std::string> measurementShortfall(const acquisition::ScanPlan& plan,
                                                const std::vector<registration::GridElement>& measurements) {
  std::vector<std::uint32_t> expected;
  for (const acquisition::PlanStep& step : plan.steps)
    if (const auto* s = std::get_if<acquisition::SweepStep>(&step); s && s->scene == acquisition::Scene::Part)
      expected.push_back(s->expected_elements);
  std::vector<std::size_t> found(expected.size(), 0);
  for (const registration::GridElement& g : measurements)
    if (g.source == registration::Source::Laser && g.view < found.size()) ++found[g.view];
  // Sweeps that expect a handful only are left out of the per-sweep test: one element more or less
  // is a large share of a few.
  constexpr std::uint32_t kFewest = 10;
  std::size_t total_expected = 0, total_found = 0;
  std::string short_sweeps;
  for (std::size_t k = 0; k < expected.size(); ++k) {
    if (expected[k] == 0) continue;
    total_expected += expected[k];
    total_found += found[k];
    if (expected[k] >= kFewest && static_cast<double>(found[k]) < kShortSweep * expected[k])
      short_sweeps += (short_sweeps.empty() ? "" : ", ") + std::to_string(k + 1) + " (" + std::to_string(found[k]) + " of " +
                      std::to_string(expected[k]) + ")";
  }
  if (total_expected == 0) return std::nullopt;
  std::string text;
  if (static_cast<double>(total_found) < kShortScan * static_cast<double>(total_expected))
    text = "the part sweeps found " + std::to_string(total_found) + " grid elements where the plan predicts " +
           std::to_string(total_expected);
  if (!short_sweeps.empty())
    text += (text.empty() ? "" : "; ") + std::string("part sweeps found much less than predicted: ") + short_sweeps;
  if (text.empty()) return std::nullopt;
  return text;
}

}  // namespace stampscan::jobs
