// `station calibrate [digitizer|cameras|all]`: the calibration scenes on the cell (calibrate_job.hpp),
// per sensor the parameters with their uncertainty, the residuals against the acceptance limits, the
// change against the calibration in use, and whether the new one is put in use. Exit 0 when every
// calibration asked for is in use, 2 when one failed its limits (and was not accepted), 1 on error.
#include "stampscan/jobs/calibrate_job.hpp"
#include "stampscan/jobs/calibration_results.hpp"
#include "stampscan/station/commands.hpp"
#include "cell_choice.hpp"
#include "stampscan/acquisition/calibration_plan.hpp"
#include "terminal_run.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <cstdio>
#include <cstdlib>
#include <memory>

namespace stampscan::station {

namespace {

struct CalibrateOptions {
  std::string what = "all", plan, calibration_dir, engineer;
  CellChoice cell;
  bool accept = false, quarter_resolution = false, quiet = false;
  VirtualWorldOptions world;
};


void printSensor(const char* name, const jobs::SensorCalibration& s) {
  const registration::CalibrationRecord& r = s.record;
  std::printf("\n  %s (record %s)\n", name, r.id.c_str());
  for (const std::string& l : s.left_out) std::printf("    left out  %s\n", l.c_str());
  for (const auto& v : r.parameters) {
    if (v.uncertainty > 0)
      std::printf("    %-36s %12.5f %-3s +- %.5f\n", v.name.c_str(), v.value, v.unit.c_str(), v.uncertainty);
    else
      std::printf("    %-36s %12.5f %s\n", v.name.c_str(), v.value, v.unit.c_str());
  }
  for (const auto& v : r.residuals)
    if (v.unit.empty())
      std::printf("    %-36s %12.0f\n", v.name.c_str(), v.value);
    else
      std::printf("    %-36s %12.5f %s\n", v.name.c_str(), v.value, v.unit.c_str());
  for (const auto& c : r.checks)
    std::printf("    %s  %s: %.4f %s (limit %.4f %s)\n", c.passed ? "PASS" : "FAIL", c.name.c_str(), c.value, c.unit.c_str(),
                c.limit, c.unit.c_str());
  for (const std::string& d : s.drift) std::printf("    DRIFT %s\n", d.c_str());
  std::printf("    verdict   %s%s; %s\n", registration::toString(r.verdict),
              r.accepted_by.empty() ? "" : (" by " + r.accepted_by).c_str(),
              s.in_use ? ("now in use" + (s.previous.empty() ? std::string() : " (replaces " + s.previous + ", kept in the history)")).c_str()
                       : "NOT put in use: the calibration in use stays (pass --accept to override)");
}

std::string loginName() {
  for (const char* var : {"SUDO_USER", "USER", "LOGNAME"})
    if (const char* v = std::getenv(var); v != nullptr && *v != '\0') return v;
  return "unknown";
}

}  // namespace

CommandRunner addCalibrateCommand(CLI::App& app) {
  auto opt = std::make_shared<CalibrateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "Calibrate the cell's sensors on the reference sphere and the plate: parameters with their "
                   "uncertainty, residuals against the acceptance limits, the change against the calibration in use; a "
                   "passing calibration is put in use (exit 2 when one fails its limits)");
  cmd->add_option("what", opt->what, "digitizer, cameras or all")->check(CLI::IsMember({"digitizer", "cameras", "all"}));
  opt->cell.addTo(cmd);
  cmd->add_option("--plan", opt->plan,
                  "The calibration plan (TOML; its sphere sweeps and plate views are used); default: the built-in one "
                  "of the virtual cell");
  cmd->add_option("-o,--calibration-dir", opt->calibration_dir,
                  "The cell's calibration folder (default: the cell's [calibration] dir, else stampscan-runs/calibration)");
  cmd->add_flag("--accept", opt->accept,
                "Put the new calibration in use even when a check fails, recorded as accepted by --engineer");
  cmd->add_option("--engineer", opt->engineer, "Who accepts with --accept (default: the login name)");
  cmd->add_flag("--quarter-resolution", opt->quarter_resolution,
                "Virtual cell: the cameras at the quarter resolution of the default (region) scan, with its 6 plate "
                "views, instead of their full resolution; the mount on the head is then known to about a millimetre "
                "only, and fails the default limit");
  opt->world.addTo(cmd);
  cmd->add_flag("-q,--quiet", opt->quiet, "No progress bar");
  return [opt]() {
    CommandCell command_cell = opt->cell.open();
    const acquisition::CellConfig& config = command_cell.config;
    const bool digitizer = opt->what != "cameras", cameras = opt->what != "digitizer";
    // The cell's calibration scenes ([calibration] plate_views, sphere_sweeps, planned for its
    // artefacts); a virtual cell's cameras at their full resolution (or the quick session's quarter,
    // to match the default scan).
    VirtualWorld world;
    world.quick = opt->quarter_resolution;
    world.options = opt->world;
    const VirtualCellHost* host = command_cell.simulate(world);
    jobs::CalibrateJobOptions job =
        jobs::cellCalibration(config, jobs::calibrationFolder(opt->calibration_dir, config.calibration), digitizer, cameras);
    job.plan = opt->plan.empty() ? jobs::cellCalibrationPlan(config, opt->world.seed, digitizer, cameras)
                                 : jobs::calibrationScenesOf(acquisition::loadScanPlan(opt->plan), digitizer, cameras);
    if (opt->accept) job.accepted_by = opt->engineer.empty() ? loginName() : opt->engineer;

    command_cell.serveToMeasure(cameras);
    acquisition::Cell cell(config);
    job.run.session = acquisition::describeSession(config.geometry, job.plan);
    job.run.session.part_id = "calibration";

    std::printf("station calibrate: %s on %s%s\n", job.plan.name.c_str(), config.name.c_str(),
                command_cell.hostedNote());
    std::printf("  priority    %s\n", command_cell.priorityNote().c_str());
    std::printf("  folder      %s\n", job.calibration_dir.c_str());
    TerminalRunObserver observer(opt->quiet);
    jobs::CalibrateJob calibrate(cell, &observer);
    const jobs::CalibrateJobResult r = runAbortable(
        observer, [&] { return calibrate.run(job); }, [&](const std::string& reason) { calibrate.abort(reason); });
    std::printf("  scenes      %zu sphere sweeps, %zu plate views in %.1f s; %llu profiles (%llu lost); trace %s\n",
                r.run.sweeps_done, r.run.views_done, r.run.wall_seconds, static_cast<unsigned long long>(r.run.profiles),
                static_cast<unsigned long long>(r.run.lost_profiles), r.trace_file.c_str());
    bool all_in_use = true;
    if (r.digitizer) {
      printSensor("digitizer", *r.digitizer);
      all_in_use = all_in_use && r.digitizer->in_use;
    }
    if (r.cameras) {
      printSensor("cameras", *r.cameras);
      all_in_use = all_in_use && r.cameras->in_use;
    }
    if (host && r.digitizer_file) {
      const VirtualSensorTruth truth = host->sensorTruth();
      const Eigen::Vector3d off = r.digitizer_file->calibration.head_from_digitizer.translation() -
                                  truth.head_from_digitizer.translation();
      std::printf("\n  truth       the virtual cell's digitizer mount is recovered to %.4f mm; latency %.3f ms (true %.3f)\n",
                  off.norm(), static_cast<double>(r.digitizer_file->calibration.latency_ns) * 1e-6,
                  static_cast<double>(truth.digitizer_latency_ns) * 1e-6);
    }
    if (host && r.cameras_file) {
      const VirtualSensorTruth truth = host->sensorTruth();
      const registration::StereoCalibration& s = r.cameras_file->stereo;
      const Eigen::Vector3d off = r.cameras_file->head_from_left.head_from_camera.translation() - truth.head_from_left.translation();
      const double true_baseline = (truth.head_from_right.translation() - truth.head_from_left.translation()).norm();
      std::printf("  truth       the cameras: left fx %.2f px (true %.2f), baseline %.4f mm (true %.4f), left mount "
                  "recovered to %.4f mm\n", s.left.model.matrix(0, 0), truth.left_fx_px, s.baseline_mm, true_baseline,
                  off.norm());
    }
    if (r.history_error.empty())
      std::printf("  history     recorded in the results database of %s\n", job.results_database.c_str());
    else
      std::fprintf(stderr, "station: warning: the records are in %s but not in the results database: %s\n",
                   (job.calibration_dir / "history").c_str(), r.history_error.c_str());
    std::printf("\n  %s\n", all_in_use ? "calibration in use updated" : "a calibration failed its limits and was not put in use");
    return all_in_use ? 0 : 2;
  };
}

}  // namespace stampscan::station
