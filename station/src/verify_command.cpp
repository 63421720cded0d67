// `station verify`: the quick daily check of the digitizer on the reference sphere (verify_job.hpp),
// with the calibration in use; pass or fail one line per check, and a record in the calibration
// history. Exit 0 when every check passes, 2 when one fails, 1 on an error.
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/jobs/calibrate_job.hpp"
#include "stampscan/jobs/calibration_results.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/jobs/verify_job.hpp"
#include "cell_choice.hpp"
#include "stampscan/acquisition/calibration_plan.hpp"
#include "terminal_run.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <cstdio>
#include <optional>
#include <filesystem>
#include <memory>

namespace stampscan::station {

namespace {

namespace fs = std::filesystem;

struct VerifyOptions {
  CellChoice cell;
  std::string plan, calibration_dir, calibration;
  std::optional<double> form_mpe_mm, size_mpe_mm;
  bool no_stereo = false;
  VirtualWorldOptions world;
  bool quiet = false;
};



void printCheck(const registration::RecordCheck& c) {
  std::printf("  %s  %s: %+.4f %s (MPE %.4f %s)\n", c.passed ? "PASS" : "FAIL", c.name.c_str(), c.value, c.unit.c_str(),
              c.limit, c.unit.c_str());
}

}  // namespace

CommandRunner addVerifyCommand(CLI::App& app) {
  auto opt = std::make_shared<VerifyOptions>();
  CLI::App* cmd = app.add_subcommand(
      "verify", "Check the digitizer on the reference sphere with the calibration in use: the probing form and size "
                "errors of ISO 10360-8 against their MPE, one line each, and a record in the calibration history "
                "(exit 2 when a check fails)");
  opt->cell.addTo(cmd);
  cmd->add_option("--plan", opt->plan,
                  "The verification plan (TOML; its sweeps over the reference sphere and the ball bar are used); "
                  "default: the built-in one of the virtual cell");
  cmd->add_option("-o,--calibration-dir", opt->calibration_dir,
                  "The cell's calibration folder: digitizer.json in use, history/ of records and their traces (default: "
                  "the cell's [calibration] dir, else stampscan-runs/calibration)");
  cmd->add_option("--calibration", opt->calibration,
                  "The digitizer calibration to verify (default: digitizer.json in the calibration folder; without "
                  "one, the sweeps calibrate the digitizer themselves)");
  cmd->add_flag("--no-stereo", opt->no_stereo, "Leave the stereo pair's check on the plate out");
  cmd->add_option("--form-mpe", opt->form_mpe_mm,
                  "MPE of the probing form error P[Form.Sph.All], mm (default: the cell's [calibration] form_mpe_mm)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--size-mpe", opt->size_mpe_mm,
                  "MPE of the probing size error |P[Size.Sph.All]|, mm (default: the cell's [calibration] size_mpe_mm)")
      ->check(CLI::PositiveNumber);
  opt->world.addTo(cmd);
  cmd->add_flag("-q,--quiet", opt->quiet, "No progress bar");
  return [opt]() {
    CommandCell command_cell = opt->cell.open();
    const acquisition::CellConfig& config = command_cell.config;
    const fs::path dir = jobs::calibrationFolder(opt->calibration_dir, config.calibration);
    jobs::VerifyJobOptions job = jobs::cellVerification(config, dir);
    if (opt->form_mpe_mm) job.sphere.form_mpe_mm = *opt->form_mpe_mm;
    if (opt->size_mpe_mm) job.sphere.size_mpe_mm = *opt->size_mpe_mm;
    const fs::path stored = opt->calibration.empty() ? dir / "digitizer.json" : fs::path(opt->calibration);
    if (!opt->calibration.empty() || fs::exists(stored)) jobs::verifyWithCalibration(job, stored);

    // The stereo pair too when its calibration is in use: three views of the plate. A virtual
    // cell's world is a quick session's, its cameras at the resolution they were calibrated at.
    VirtualWorld world;
    world.quick = true;
    world.image_scale = 1;
    world.options = opt->world;
    if (const fs::path cameras = dir / "cameras.json"; fs::exists(cameras) && !opt->no_stereo) {
      job.cameras = registration::loadCameraCalibration(cameras);
      job.stereo = {config.calibration.stereo_form_mpe_mm, config.calibration.stereo_length_mpe_mm};
      world.image_scale = static_cast<double>(job.cameras->stereo.left.model.size.width) / config.geometry.cameras.width;
    }
    command_cell.simulate(world);
    const std::size_t plate_views = job.cameras ? 3 : 0;
    job.plan = opt->plan.empty() ? jobs::cellVerificationPlan(config, opt->world.seed, plate_views)
                                 : jobs::verificationStepsOf(acquisition::loadScanPlan(opt->plan), plate_views);
    // The embedded virtual cell first (it may re-execute this program); cameras only for plate views.
    command_cell.serveToMeasure(job.plan.stereoCount() > 0);
    acquisition::Cell cell(config);
    // The cell's geometry as drawn, the sphere's certified diameter with it.
    job.run.session = acquisition::describeSession(config.geometry, job.plan);
    job.run.session.part_id = "reference sphere";

    std::printf("station verify: %s on %s%s\n", job.plan.name.c_str(), config.name.c_str(),
                command_cell.hostedNote());
    std::printf("  priority    %s\n", command_cell.priorityNote().c_str());
    std::printf("  calibration %s\n", job.calibration ? job.calibration_source.c_str()
                                                      : "none in use: the sweeps calibrate the digitizer themselves");
    TerminalRunObserver observer(opt->quiet);
    jobs::VerifyJob verify(cell, &observer);
    const jobs::VerifyJobResult r = runAbortable(
        observer, [&] { return verify.run(job); }, [&](const std::string& reason) { verify.abort(reason); });
    const registration::SphereVerification& v = r.digitizer;
    std::printf("  sweeps      %zu over the spheres, %llu profiles (%llu lost) in %.1f s\n", r.run.sweeps_done,
                static_cast<unsigned long long>(r.run.profiles), static_cast<unsigned long long>(r.run.lost_profiles),
                r.run.wall_seconds);
    if (r.calibrated)
      std::printf("  calibrated  latency %.3f ms, residual %.4f mm RMS over %zu points\n",
                  static_cast<double>(r.calibrated->calibration.latency_ns) * 1e-6, r.calibrated->rms_mm,
                  r.calibrated->inliers);
    std::printf("  sphere      %zu of %zu points on it; fitted diameter %.4f mm (certified %.4f), radial RMS %.4f mm\n",
                v.points_on_sphere, v.points_measured, 2 * v.fit.radius, 2 * v.fit.radius - v.size_error_mm,
                v.fit.rms_mm);
    if (r.stereo)
      std::printf("  stereo      %zu plate views, %zu dots; lengths up to %.1f mm, RMS error %.4f mm\n", r.stereo->views,
                  r.stereo->dots, r.stereo->longest_length_mm, r.stereo->rms_length_error_mm);
    for (const auto& c : r.record.checks) printCheck(c);
    if (r.second_sphere)
      std::printf("  ball bar    second sphere: %zu points, fitted diameter %.4f mm; centre distance %.4f mm (certified %.4f)\n",
                  r.second_sphere->points_on_sphere, 2 * r.second_sphere->fit.radius, *r.distance_mm, job.ball_bar->distance_mm);

    std::printf("  record      %s (%s)\n", r.record.id.c_str(), r.record_file.c_str());
    if (r.history_error.empty())
      std::printf("  history     recorded in the results database of %s\n", job.results_database.c_str());
    else
      std::fprintf(stderr, "station: warning: the verification is recorded in %s but not in the results database: %s\n",
                   r.record_file.c_str(), r.history_error.c_str());
    std::printf("  verdict     %s\n", r.passed() ? "PASSED" : "FAILED");
    return r.passed() ? 0 : 2;
  };
}

}  // namespace stampscan::station
