// `station scan`: a part on the cell, from the interlocks to its measured strain. A thin caller of
// ScanJob (scan_job.hpp: the plan through acquisition::ScanRunner into the run folder's trace, then
// registration::measureScan and the fit). Without --cell it hosts the virtual cell in this process
// (the part, sphere and plate in one simulated world) and talks to it only through the drivers on
// loopback, as to a real cell.
#include "stampscan/acquisition/cell.hpp"
#include "stampscan/acquisition/plan_collisions.hpp"
#include "stampscan/jobs/calibrate_job.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/jobs/progress.hpp"
#include "stampscan/jobs/scan_job.hpp"
#include "cell_choice.hpp"
#include "program_library.hpp"
#include "scan_terminal.hpp"
#include "stop_signals.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <cstdio>
#include <optional>

namespace stampscan::station {

namespace {

struct ScanOptions {
  CellChoice cell;
  std::string plan, part = "pan", grid = "circle", part_id = "sample", runs = "stampscan-runs", replay;
  std::string material, press_program, part_program, calibration_dir;
  bool dry_run = false, whole_part = false, laser_only = false, quiet = false, accept_damaged = false, calibrated = false;
  VirtualWorldOptions world;
};

void addScanOptions(CLI::App* cmd, ScanOptions& opt) {
  opt.cell.addTo(cmd);
  cmd->add_option("--plan", opt.plan,
                  "Scan plan (TOML), the part's steps in its datum frame (placed on the cell's fixture); with "
                  "--replay, the plan as the machine ran it; default: the part program's");
  cmd->add_option("--part", opt.part,
                  "Virtual cell without --program: its own part on the fixture (scanned as the program "
                  "sim-PART-GRID, or sim-PART-GRID-sample for its sample region)")
      ->check(CLI::IsMember({"pan", "dome"}));
  cmd->add_option("--grid", opt.grid, "Virtual cell without --program: its part's printed grid")
      ->check(CLI::IsMember({"circle", "square"}));
  cmd->add_option("--part-id", opt.part_id, "The part's id, for the run folder and the record");
  cmd->add_option("-o,--runs", opt.runs, "Folder of run folders (created when missing)");
  cmd->add_option("--material", opt.material, "The sheet's material, for the forming-limit report (see `station report "
                                               "--list-materials`; default DC04)");
  cmd->add_option("--program", opt.part_program,
                  "The part program to scan: its name in the cell's program library ([programs] library; on a virtual "
                  "cell RUNS_DIR/programs, where it writes its own sim-dome-circle, sim-pan-square, ...), or its folder. "
                  "Its plan, grid and material; --part and --grid do not apply");
  cmd->add_option("--press-program", opt.press_program,
                  "The press program the part comes from, for the report and the history (default: the part program's)");
  cmd->add_flag("--whole-part", opt.whole_part,
                "Virtual cell without --program: scan its whole part (default: its 40 x 30 mm sample region, at a "
                "quarter of the cameras' resolution, about 40 s)");
  cmd->add_flag("--laser-only", opt.laser_only, "Leave the stereo views out of the plan (built-in or the program's)");
  cmd->add_flag("--calibrated", opt.calibrated,
                "Leave the calibration scenes out of the built-in plan and measure with the calibration in use (from "
                "`station calibrate`; refused when it is missing, failed, expired or not this cell's)");
  cmd->add_option("--calibration-dir", opt.calibration_dir,
                  "The cell's calibration folder (default: the cell's [calibration] dir, else RUNS_DIR/calibration)");
  opt.world.addTo(cmd);
  cmd->add_option("--replay", opt.replay,
                  "Run a recorded trace again on the virtual cell (the CMM follows its head track, the digitizer and "
                  "the cameras serve its profiles and frames) and compare the result with `station process` on it");
  cmd->add_flag("--dry-run", opt.dry_run, "Check the plan against the cell and print it; nothing moves");
  cmd->add_flag("--accept-damaged", opt.accept_damaged,
                "Exit 0 even when the scan lost data (missing stereo views, sweeps over the profile-loss limit)");
  cmd->add_flag("-q,--quiet", opt.quiet, "No progress bar");
}

// The part program to scan, with its material and press program unless given: the one named, or
// without a program, a plan or a recording to replay, the virtual cell's own sample (the sample
// region of its part: quarter-resolution images, half the calibration scenes; or the whole part).
// A real cell has no part of its own.
std::optional<acquisition::PartProgram> programOf(ScanOptions& opt, const acquisition::CellConfig& config, bool quick,
                                                  const report::MaterialLibrary& materials) {
  const bool virtual_cell = opt.cell.hosted();
  if (opt.part_program.empty() && opt.plan.empty() && opt.replay.empty()) {
    if (!virtual_cell)
      throw std::runtime_error(config.source + ": which part? Give its program (--program NAME or FOLDER) or a scan "
                               "plan (--plan FILE); a real cell has no built-in part");
    opt.part_program = simulatedProgramName(opt.part, opt.grid, quick);
  }
  if (opt.part_program.empty()) return std::nullopt;
  acquisition::PartProgram program = programToScan(opt.part_program, config, virtual_cell, opt.runs);
  if (opt.material.empty()) opt.material = program.material;
  if (opt.press_program.empty()) opt.press_program = program.press_program;
  if (!opt.material.empty()) (void)materials.find(opt.material);
  return program;
}

// The plan: a recording's (a replay plays it on a virtual cell, `host`, that serves the recording),
// the program's, or a plan file's, the last two placed on the cell's fixture.
void choosePlan(ScanOptions& opt, const acquisition::CellConfig& config, const std::optional<acquisition::PartProgram>& program,
                bool quick, VirtualCellHost* host, jobs::ScanJobOptions& job) {
  const bool replay = !opt.replay.empty();
  if (replay) {
    if (!host) throw std::runtime_error("--replay runs on a virtual cell: leave --cell out, or add --virtual");
    if (!opt.dry_run) requireUmockdevPreload();  // may run this program again: before the recording is read
    RecordedSession recorded = host->replay(opt.replay, opt.accept_damaged, opt.plan);
    job.plan = std::move(recorded.plan);
    job.run.session = std::move(recorded.session);
    if (opt.part_id == "sample" && !job.run.session.part_id.empty()) opt.part_id = job.run.session.part_id;
    job.replayed_trace = opt.replay;
  } else if (program && opt.plan.empty()) {
    job.plan = programPlan(*program, config,
                           acquisition::calibrationScenes(config.calibration, quick ? 0.5 : 1.0, opt.world.seed),
                           !opt.calibrated);
  } else {
    // A plan file, like a program's plan, gives the part's steps in its datum frame.
    job.plan = acquisition::placeOnFixture(acquisition::loadScanPlan(opt.plan), config.geometry, config.limits.index_step);
  }
  if (opt.plan.empty() && !replay) {
    if (opt.laser_only)
      std::erase_if(job.plan.steps, [](const acquisition::PlanStep& s) { return std::holds_alternative<acquisition::StereoStep>(s); });
    job.plan.name = (program ? program->name : job.plan.part.kind) + (opt.laser_only ? ", laser" : ", laser and stereo") +
                    (opt.calibrated ? ", on the calibration in use" : ", with calibration scenes");
  }
}

void printResult(const jobs::ScanJobResult& r, const jobs::ScanJobOptions& job, const VirtualCellHost* host) {
  const bool hosted = host != nullptr;
  std::printf("  measured    %zu grid elements (%zu measurements); cloud4d.ply %.2f s after the scan; fitted.ply, mesh.ply "
              "%.2f s after it\n",
              r.elements, r.measurements, r.cloud4d_seconds, r.measure_seconds);
  std::printf("  calibration digitizer: %s; cameras: %s\n", r.digitizer_calibration.c_str(), r.camera_calibration.c_str());
  if (r.accuracy && hosted)
    std::printf("  accuracy    against the simulated part: %zu of %zu elements matched, position RMS %.4f mm, "
                "thickness strain RMS %.4f; latency %.3f ms (true %.3f)\n",
                r.accuracy->matched, r.elements, r.accuracy->position_rms_mm, r.accuracy->strain_rms,
                static_cast<double>(r.digitizer.latency_ns) * 1e-6,
                static_cast<double>(job.truth->digitizer_latency_ns) * 1e-6);
  if (r.accuracy && hosted && r.accuracy->laser.matched > 0 && r.accuracy->stereo.matched > 0)
    std::printf("  by sensor   laser-led %lld elements %.4f mm, strain %.4f; stereo-led %lld elements %.4f mm, strain %.4f\n",
                static_cast<long long>(r.accuracy->laser.matched), r.accuracy->laser.position_rms_mm,
                r.accuracy->laser.strain_rms, static_cast<long long>(r.accuracy->stereo.matched),
                r.accuracy->stereo.position_rms_mm, r.accuracy->stereo.strain_rms);
  if (r.accuracy && r.accuracy->visible > 0)
    std::printf("  visible     %zu of %zu visible elements found (%.1f %%; a sensor sees them whole from a pose of the "
                "plan); %zu more found that none sees whole\n",
                r.accuracy->visible_found, r.accuracy->visible,
                100.0 * static_cast<double>(r.accuracy->visible_found) / static_cast<double>(r.accuracy->visible),
                r.accuracy->found_not_visible);
  if (r.accuracy && hosted && r.accuracy->with_uncertainty > 0)
    std::printf("  uncertainty %.1f %% of %zu elements' true strain within their stated expanded uncertainty (k = 2)\n",
                100.0 * r.accuracy->within_expanded_uncertainty, r.accuracy->with_uncertainty);
  if (const auto& f = r.surface_accuracy; f && hosted && f->elements > 0)
    std::printf("  surface     strain RMS %.4f at %lld elements (theirs %.4f), %.4f at %lld points halfway between "
                "them; %lld of %lld points within the grid without strain\n",
                f->at_elements_rms, static_cast<long long>(f->elements), f->elements_own_rms, f->between_rms,
                static_cast<long long>(f->between_points), static_cast<long long>(f->within_grid_without_strain),
                static_cast<long long>(f->within_grid_points));
  if (host) host->printReplay(r);
  if (r.report) {
    std::printf("  verdict     %s: %s (material %s); report.pdf, report.html, fld.png, strain maps (%.1f s)\n",
                report::toString(r.report->verdict), r.report->verdict_reason.c_str(), r.report->material.c_str(),
                r.report->seconds);
  }
  std::printf("  results     %s\n", r.run_dir.c_str());
}

// 0, or 1 when the report failed or the scan lost data (unless accepted).
int exitStatus(const jobs::ScanJobResult& r, bool accept_damaged) {
  if (!r.history_error.empty())
    std::fprintf(stderr, "station: warning: the run is complete but not in the results history: %s\n",
                 r.history_error.c_str());
  if (!r.report_error.empty()) {
    std::fprintf(stderr, "station: error: the scan is measured, but its report failed: %s (run `station report %s` "
                         "once the cause is fixed)\n", r.report_error.c_str(), r.run_dir.c_str());
    return 1;
  }
  if (r.data_loss) {
    if (!accept_damaged) {
      std::fprintf(stderr, "station: error: the scan lost data: %s. The results lack those elements (run.json says "
                           "so); scan again, or pass --accept-damaged to accept such a result\n", r.data_loss->c_str());
      return 1;
    }
    std::printf("  accepted    an incomplete scan (--accept-damaged): %s\n", r.data_loss->c_str());
  }
  return 0;
}

// --dry-run: the plan checked against the cell's limits and, with a program, its model: what the
// plan is predicted to see and the head's clearance along it. 0 when it can run.
int dryRun(const jobs::ScanJobOptions& job, const acquisition::CellConfig& config,
           const std::optional<acquisition::PartProgram>& program) {
  auto problems = acquisition::checkPlan(job.plan, job.run.limits);
  std::optional<acquisition::Coverage> coverage;
  if (program) {
    const acquisition::NominalModel placed = acquisition::placeOnFixture(program->model, config.geometry);
    coverage = acquisition::predictCoverage(placed, job.plan, config.geometry, job.run.limits);
    const acquisition::CollisionOptions clearance;
    for (const acquisition::PlanCollision& c :
         acquisition::checkCollisions(placed, config.geometry.fixture.body, acquisition::toRigidPose(config.geometry.fixture.datum),
                                      job.plan, config.geometry.head, clearance))
      problems.push_back(acquisition::describe(c, job.plan, clearance.clearance_mm));
  }
  printDryRun(job.plan, config, job.run.limits, problems, coverage ? &*coverage : nullptr);
  return problems.empty() ? 0 : 1;
}

// The virtual twin's world for the scan: the program's part (or --part's, for a plan file).
VirtualWorld scanWorld(const ScanOptions& opt, bool quick) {
  VirtualWorld world;
  world.quick = quick;
  world.part = opt.part;
  world.grid = opt.grid;
  world.calibration_artefacts = !opt.calibrated;
  world.options = opt.world;
  return world;
}

int runScan(ScanOptions& opt) {
  CommandCell cell = opt.cell.open();
  // An unknown material is refused before anything moves (the report at the end would fail).
  const report::MaterialLibrary materials = report::materialsWith(cell.config.materials_file);
  if (!opt.material.empty()) (void)materials.find(opt.material);
  const bool quick = !opt.whole_part && opt.part_program.empty();
  const std::optional<acquisition::PartProgram> program = programOf(opt, cell.config, quick, materials);
  if (VirtualCellHost* host = cell.simulate(scanWorld(opt, quick)); host && program) host->useProgram(*program);

  jobs::ScanJobOptions job;
  job.calibration_policy = cell.config.calibration;
  job.calibration_dir = jobs::calibrationFolder(opt.calibration_dir, cell.config.calibration, opt.runs);
  job.run.limits = cell.config.limits;
  choosePlan(opt, cell.config, program, quick, cell.host.get(), job);
  if (opt.dry_run) return dryRun(job, cell.config, program);

  cell.serveToMeasure(job.plan.stereoCount() > 0);
  // The planner's prediction of what each sweep sees, against which the scan is checked, too.
  if (cell.host && !cell.host->replaying()) job.truth = cell.host->truthOfScan(job.plan);
  const acquisition::CellConfig& config = cell.config;
  acquisition::Cell devices(config);
  job.part_id = opt.part_id;
  job.runs_dir = opt.runs;
  job.results_database = config.results_database;
  job.material = opt.material;
  job.materials = &materials;
  job.program = opt.press_program;
  if (program) job.part_program = jobs::PartProgramRef{program->name, program->folder.string()};
  // The cell's geometry as drawn, from its file: what calibration starts from (a replay's is the
  // recording's).
  if (opt.replay.empty()) job.run.session = acquisition::describeSession(config.geometry, job.plan);
  job.run.session.part_id = opt.part_id;

  std::printf("station scan: %s on %s%s\n", job.plan.name.c_str(), config.name.c_str(), cell.hostedNote());
  std::printf("  priority    %s\n", cell.priorityNote().c_str());
  if (program)
    std::printf("  program     %s (%s): %s grid %.2f mm, %s %.2f mm; model %zu triangles\n", program->name.c_str(),
                program->folder.c_str(), program->grid.kind.c_str(), program->grid.pitch_mm, program->material.c_str(),
                program->sheet_thickness_mm, program->model.triangles.size());
  TerminalObserver observer(opt.quiet);
  jobs::ScanJob scan(devices, &observer);
  jobs::ScanJobResult r;
  {
    const StopSignalGuard stop([&](const std::string& reason) { scan.abort(reason); });
    r = scan.run(job);
  }
  printResult(r, job, cell.host.get());
  return exitStatus(r, opt.accept_damaged);
}

}  // namespace

CommandRunner addScanCommand(CLI::App& app) {
  auto opt = std::make_shared<ScanOptions>();
  CLI::App* cmd = app.add_subcommand("scan", "Scan a part on the cell: checks, the plan's sweeps, then the measured "
                                             "strain (default: the sample pan on the built-in virtual cell)");
  addScanOptions(cmd, *opt);
  return [opt]() { return runScan(*opt); };
}

}  // namespace stampscan::station
