// `station process TRACE.mcap -o CLOUD4D.ply`: the measuring path on a recorded or simulated trace,
// a thin caller of registration::measureScan (measure_scan.hpp says what it does). With --fit it
// also fits the surface; --save-calibration keeps the calibrations the trace gave.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/registration/measure_scan.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/jobs/fit_runner.hpp"
#include "stampscan/jobs/progress.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>

namespace stampscan::station {

namespace fs = std::filesystem;

namespace {

struct ProcessOptions {
  std::string input, output, measurements, fit, mesh, calibration_dir, save_calibration;
  bool ascii = false, quiet = false, with_stereo = false, accept_damaged = false;
};

void checkFolder(const std::string& file, const char* what) {
  if (file.empty()) return;
  const fs::path parent = fs::absolute(file).parent_path();
  if (!fs::is_directory(parent)) throw std::runtime_error(std::string(what) + " folder '" + parent.string() + "' does not exist");
}

// Each stage's line, aligned under the command's header.
class PrintingObserver final : public registration::MeasureObserver {
 public:
  void stageDone(std::string_view stage, const std::string& text) override {
    std::printf("  %-11.*s %s\n", static_cast<int>(stage.size()), stage.data(), text.c_str());
  }
};

void printTraceSummary(const registration::ScanTrace& trace, double read_seconds) {
  std::printf("  trace       %llu messages, %zu profiles, %zu plate frame pairs, %zu part frames; scan %.1f s (%.2f s)\n",
              static_cast<unsigned long long>(trace.health.messages_delivered), trace.profiles.size(),
              trace.plate_left.size(), trace.part_frames, trace.scan_seconds, read_seconds);
  if (trace.health.truncated)
    std::printf("  warning     the trace is cut at byte %llu; every complete message before it is used\n",
                static_cast<unsigned long long>(trace.health.truncated->file_size));
  for (const auto& d : trace.health.damage)
    std::printf("  warning     damage at byte %llu: %s\n", static_cast<unsigned long long>(d.offset), d.what.c_str());
}


// Every output's folder exists, and the options go together, before anything is read.
void checkOutputs(const ProcessOptions& opt) {
  checkFolder(opt.output, "output");
  checkFolder(opt.measurements, "measurements output");
  checkFolder(opt.fit, "fit output");
  checkFolder(opt.mesh, "mesh output");
  if (!opt.mesh.empty() && opt.fit.empty()) throw std::runtime_error("--mesh needs --fit");
  if (!opt.save_calibration.empty() && !fs::is_directory(opt.save_calibration))
    throw std::runtime_error("calibration folder '" + opt.save_calibration + "' does not exist");
}

// The measuring parameters: the stereo views when asked, the laser's returns kept for a fit, and
// the calibration in use for a trace without reference-sphere sweeps (or the cameras' without plate
// views).
registration::MeasureParams measureParams(const ProcessOptions& opt, const registration::ScanTrace& trace) {
  registration::MeasureParams params;
  params.with_stereo = opt.with_stereo;
  params.keep_surface_points = !opt.fit.empty();
  const bool has_sphere = std::any_of(trace.sweeps.begin(), trace.sweeps.end(),
                                      [](const registration::SweepWindow& w) { return w.is(trace::Scene::ReferenceSphere); });
  if (!has_sphere && opt.calibration_dir.empty())
    throw std::runtime_error(opt.input + " has no reference-sphere sweeps to calibrate the digitizer: pass "
                                         "--calibration DIR with a digitizer.json");
  if (!opt.calibration_dir.empty()) {
    const fs::path file = fs::path(opt.calibration_dir) / "digitizer.json";
    if (!fs::exists(file)) throw std::runtime_error(file.string() + " does not exist");
    params.digitizer = registration::loadDigitizerCalibration(file).calibration;
    if (const fs::path cameras = fs::path(opt.calibration_dir) / "cameras.json"; fs::exists(cameras))
      params.cameras = registration::loadCameraCalibration(cameras);
  }
  return params;
}

// --save-calibration: the calibrations the trace made, written as one set.
void saveCalibrations(const ProcessOptions& opt, const registration::ScanMeasurement& m) {
  std::optional<registration::DigitizerCalibrationFile> digitizer;
  std::optional<registration::CameraCalibrationFile> cameras;
  if (m.sphere)
    digitizer = registration::DigitizerCalibrationFile{m.sphere->calibration, m.sphere->rms_mm, m.sphere->inliers,
                                                       registration::utcNow(), opt.input + " (reference-sphere sweeps)", {}};
  if (m.stereo)
    cameras = registration::CameraCalibrationFile{*m.stereo, m.head_from_left.value_or(registration::HandEyeResult{}),
                                                  registration::utcNow(), opt.input + " (calibration-plate views)", {}};
  registration::saveCalibrationSet(opt.save_calibration, digitizer ? &*digitizer : nullptr, cameras ? &*cameras : nullptr);
}

// --fit: the shape from every laser return, the elements' strain on it; the Cloud4D again with the
// surface's strain at each element beside the element's own.
void fitSurface(const ProcessOptions& opt, registration::ScanMeasurement& m, fitting::Cloud& cloud,
                const fitting::PlyWriteOptions& w) {
  if (m.surface_points.empty())
    throw std::runtime_error(opt.input + ": the part sweeps have no laser returns to fit a surface to");
  const auto shape = jobs::runShapeFit(std::move(m.surface_points), !opt.quiet);
  const fitting::ShapeAndStrain fit = jobs::runStrainOnShape(*shape, cloud);
  jobs::printShapeAndStrainSummary(fit);
  cloud.scalars[fitting::kFittedStrain] = fit.strain_at_carriers;
  fitting::writePly(opt.output, cloud, w);
  fitting::writePly(opt.fit, fit.surface, w);
  if (!opt.mesh.empty()) fitting::writePly(opt.mesh, fit.mesh, w);
}

int runProcess(const ProcessOptions& opt) {
  checkOutputs(opt);
  const auto start = std::chrono::steady_clock::now();
  const auto since = [&start] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  std::printf("station process: %s\n", opt.input.c_str());
  registration::ScanTrace trace;
  {
    jobs::ProgressBar bar;
    trace = registration::loadScanTrace(
        opt.input,
        [&](double f) {
          if (!opt.quiet) bar.update("reading", f);
        },
        opt.with_stereo);
  }
  printTraceSummary(trace, since());
  // A result from a trace that lost data would silently miss elements: it takes an explicit choice.
  if (const std::optional<std::string> loss = stampscan::trace::describeDataLoss(trace.health)) {
    if (!opt.accept_damaged)
      throw std::runtime_error(opt.input + " is damaged: " + *loss +
                               ". Its result would miss what was lost; pass --accept-damaged to measure what remains");
    std::printf("  accepted    a damaged trace (--accept-damaged): %s\n", loss->c_str());
  }
  const registration::MeasureParams params = measureParams(opt, trace);
  PrintingObserver observer;
  registration::ScanMeasurement m;
  try {
    m = registration::measureScan(trace, params, &observer);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(opt.input + ": " + e.what());
  }
  if (!opt.save_calibration.empty()) saveCalibrations(opt, m);

  // The Cloud4D: one point per printed element, its measurements by every sweep and view merged.
  fitting::Cloud cloud = registration::toCloud(m.merged.elements);
  fitting::PlyWriteOptions w;
  w.format = opt.ascii ? fitting::PlyFormat::Ascii : fitting::PlyFormat::BinaryLittleEndian;
  w.comment = "StampScan Cloud4D from " + fs::path(opt.input).filename().string();
  fitting::writePly(opt.output, cloud, w);
  std::printf("  wrote       %s: %zu grid elements\n", opt.output.c_str(), cloud.size());
  if (!opt.measurements.empty()) {
    fitting::PlyWriteOptions wm = w;
    wm.comment = "StampScan measurements of the grid elements from " + fs::path(opt.input).filename().string();
    fitting::writePly(opt.measurements, registration::toCloud(m.elements), wm);
    std::printf("  wrote       %s: %zu measurements\n", opt.measurements.c_str(), m.elements.size());
  }
  if (!opt.fit.empty()) {
    const double before = since();
    fitSurface(opt, m, cloud, w);
    std::printf("  fit         %s (%.2f s)\n", opt.fit.c_str(), since() - before);
    if (!opt.mesh.empty()) std::printf("  mesh        %s\n", opt.mesh.c_str());
  }
  const double total_s = since();
  std::printf("  time        %.2f s for a %.1f s scan (%.1fx faster than the scan)\n", total_s, trace.scan_seconds,
              trace.scan_seconds / std::max(total_s, 1e-9));
  return 0;
}

}  // namespace

CommandRunner addProcessCommand(CLI::App& app) {
  auto opt = std::make_shared<ProcessOptions>();
  CLI::App* cmd = app.add_subcommand("process", "Measure a scan trace: calibration, laser profiles to the machine "
                                                "frame, printed circles, strains; writes a Cloud4D PLY");
  cmd->add_option("trace", opt->input, "Recorded or simulated trace (.mcap)")->required();
  cmd->add_option("-o,--output", opt->output, "Cloud4D PLY of the grid elements")->required();
  cmd->add_option("--measurements", opt->measurements,
                  "Also write every measurement of every element (each sweep's and view's, with its source, view and "
                  "standard uncertainties); the Cloud4D holds one merged point per printed element");
  cmd->add_option("--fit", opt->fit,
                  "Also fit the surface: its shape from every laser return, the grid elements' strain on it; "
                  "written as points 0.5 mm apart with normals and strain");
  cmd->add_option("--mesh", opt->mesh, "Also write that surface as a triangle mesh with strain (needs --fit)");
  cmd->add_option("--calibration", opt->calibration_dir,
                  "Folder with digitizer.json (and cameras.json), used when the trace has no calibration scenes");
  cmd->add_option("--save-calibration", opt->save_calibration, "Write the calibrations made from the trace to this folder");
  cmd->add_flag("--with-stereo", opt->with_stereo,
                "Also measure the stereo views (matched on the laser's surface, registered to it by ICP)");
  cmd->add_flag("--accept-damaged", opt->accept_damaged,
                "Measure what remains of a damaged or cut trace (without it such a trace is refused, exit 1)");
  cmd->add_flag("--ascii", opt->ascii, "Write ASCII PLY");
  cmd->add_flag("-q,--quiet", opt->quiet, "No progress bar");
  return [opt]() { return runProcess(*opt); };
}

}  // namespace stampscan::station
