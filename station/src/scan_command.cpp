// `station scan`: a part on the cell, from the interlocks to its measured strain. A thin caller of
// ScanJob (scan_job.hpp: the plan through acquisition::ScanRunner into the run folder's trace, then
// registration::measureScan and the fit). Without --cell it hosts the virtual cell in this process
// (the part, sphere and plate in one simulated world) and talks to it only through the drivers on
// loopback, as to a real cell.
#include "stampscan/acquisition/cell.hpp"
#include "stampscan/sim/cell_replay.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/station/calibrate_job.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/station/progress.hpp"
#include "stampscan/station/scan_job.hpp"
#include "stop_signals.hpp"
#include "virtual_digitizer_host.hpp"

#include <cstdio>

namespace stampscan::station {

namespace {

struct ScanOptions {
  std::string cell, plan, part = "pan", grid = "circle", part_id = "sample", runs = "stampscan-runs", replay;
  std::string material, program, calibration_dir;
  bool dry_run = false, whole_part = false, laser_only = false, quiet = false, accept_damaged = false, calibrated = false;
  std::uint64_t seed = 1;
  std::vector<double> mount_shift;
};


class TerminalObserver final : public ScanJobObserver {
 public:
  explicit TerminalObserver(bool quiet) : quiet_(quiet) {}
  void runFolder(const std::filesystem::path& dir) override {
    std::printf("  run folder  %s\n", dir.c_str());
    std::fflush(stdout);
  }
  void checkPassed(const std::string& what) override { std::printf("  check       %s\n", what.c_str()); }
  void progress(const acquisition::ScanProgress& p) override {
    if (quiet_) return;
    char text[160];
    std::snprintf(text, sizeof text, "%s  %llu profiles, ETA %.0f s", p.doing.c_str(),
                  static_cast<unsigned long long>(p.profiles), p.remaining_s);
    bar_.update(text, p.steps ? static_cast<double>(p.step) / static_cast<double>(p.steps) : 0.0);
  }
  void safetyEvent(const std::string& what) override { std::printf("  safety      %s\n", what.c_str()); }
  void scanDone(const acquisition::ScanRunResult& r) override {
    bar_.finish();
    std::printf("  scan        %zu sweeps and %zu stereo views in %.1f s (the plan's motion: %.1f s); %llu profiles "
                "(%llu lost), %llu positions%s\n",
                r.sweeps_done, r.views_done, r.wall_seconds, r.motion_seconds, static_cast<unsigned long long>(r.profiles),
                static_cast<unsigned long long>(r.lost_profiles), static_cast<unsigned long long>(r.positions),
                r.views_missing ? (", " + std::to_string(r.views_missing) + " views missing").c_str() : "");
  }
  void stageDone(std::string_view stage, const std::string& text) override {
    bar_.finish();
    std::printf("  %-11.*s %s\n", static_cast<int>(stage.size()), stage.data(), text.c_str());
  }

 private:
  bool quiet_;
  ProgressBar bar_;
};

void printDryRun(const acquisition::ScanPlan& plan, const acquisition::CellConfig& cell,
                 const acquisition::MachineLimits& limits, const std::vector<std::string>& problems) {
  std::printf("station scan --dry-run: plan '%s' on %s\n", plan.name.c_str(), cell.name.c_str());
  std::printf("  part        %s, %s grid\n", plan.part.kind.c_str(), plan.part.grid.c_str());
  std::printf("  steps       %zu sweeps (%zu on the part, %zu on the reference sphere), %zu stereo views\n",
              plan.sweepCount(), plan.sweepCount(acquisition::kScenePart), plan.sweepCount(acquisition::kSceneSphere),
              plan.stereoCount());
  std::printf("  motion      %.1f s\n", acquisition::motionSeconds(plan, limits));
  for (const std::string& p : problems) std::printf("  problem     %s\n", p.c_str());
  std::printf("  %s\n", problems.empty() ? "the plan can run on this cell" : "the plan cannot run on this cell");
}

// What the replay served, and its result against `station process` on the recording (ScanJob
// measured both).
void printReplay(const sim::CellReplay& replay, const ScanJobResult& r) {
  const sim::ReplayStats s = replay.stats();
  std::printf("  replay      followed %zu recorded moves (%zu not in the recording), served %zu recorded profiles "
              "(%zu ticks without one), %zu frames\n",
              s.moves_followed, s.moves_not_recorded, s.profiles_served, s.profiles_missing, s.frames_served);
  if (const auto& a = r.against_recording)
    std::printf("  against     station process on the recording (%zu elements): %zu of %zu matched, position RMS %.4f mm, "
                "thickness strain RMS %.5f\n",
                r.recording_elements, a->matched, r.elements, a->position_rms_mm, a->strain_rms);
}

}  // namespace

CommandRunner addScanCommand(CLI::App& app) {
  auto opt = std::make_shared<ScanOptions>();
  CLI::App* cmd = app.add_subcommand("scan", "Scan a part on the cell: checks, the plan's sweeps, then the measured "
                                             "strain (default: the sample pan on the built-in virtual cell)");
  cmd->add_option("--cell", opt->cell, "Cell configuration (TOML); default: the built-in virtual cell, hosted here");
  cmd->add_option("--plan", opt->plan, "Scan plan (TOML); default: the built-in plan for --part");
  cmd->add_option("--part", opt->part, "Built-in plan and, on the virtual cell, the part on the fixture")
      ->check(CLI::IsMember({"pan", "dome"}));
  cmd->add_option("--grid", opt->grid, "The virtual part's printed grid")->check(CLI::IsMember({"circle", "square"}));
  cmd->add_option("--part-id", opt->part_id, "The part's id, for the run folder and the record");
  cmd->add_option("-o,--runs", opt->runs, "Folder of run folders (created when missing)");
  cmd->add_option("--material", opt->material, "The sheet's material, for the forming-limit report (see `station report "
                                               "--list-materials`; default DC04)");
  cmd->add_option("--program", opt->program, "The press program the part comes from, for the report and the history");
  cmd->add_flag("--whole-part", opt->whole_part, "Scan the whole part (default: a 40 x 30 mm region, about 40 s)");
  cmd->add_flag("--laser-only", opt->laser_only, "Leave the stereo views out of the built-in plan");
  cmd->add_flag("--calibrated", opt->calibrated,
                "Leave the calibration scenes out of the built-in plan and measure with the calibration in use (from "
                "`station calibrate`; refused when it is missing, failed, expired or not this cell's)");
  cmd->add_option("--calibration-dir", opt->calibration_dir,
                  "The cell's calibration folder (default: the cell's [calibration] dir, else RUNS_DIR/calibration)");
  cmd->add_option("--seed", opt->seed, "The virtual cell's seed (sensor noise, the digitizer mount's deviation)");
  cmd->add_option("--shift-digitizer-mount", opt->mount_shift,
                  "Virtual cell: knock the digitizer's true mount by X,Y,Z mm (head frame), as if it had moved")
      ->expected(3)
      ->delimiter(',');
  cmd->add_option("--replay", opt->replay,
                  "Run a recorded trace again on the virtual cell (the CMM follows its head track, the digitizer and "
                  "the cameras serve its profiles and frames) and compare the result with `station process` on it");
  cmd->add_flag("--dry-run", opt->dry_run, "Check the plan against the cell and print it; nothing moves");
  cmd->add_flag("--accept-damaged", opt->accept_damaged,
                "Exit 0 even when the scan lost data (missing stereo views, sweeps over the profile-loss limit)");
  cmd->add_flag("-q,--quiet", opt->quiet, "No progress bar");
  return [opt]() {
    const bool virtual_cell = opt->cell.empty();
    // An unknown material is refused before anything moves (the report at the end would fail).
    if (!opt->material.empty()) (void)report::builtInMaterials().find(opt->material);
    acquisition::CellConfig config = virtual_cell ? acquisition::virtualCell() : acquisition::loadCellConfig(opt->cell);

    // The virtual world, and the built-in plan for its part (or the plan file).
    sim::ScanParams world = opt->whole_part ? sim::ScanParams{} : sim::ScanParams::quick();
    world.part = opt->part == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan;
    world.grid.kind = sim::gridKindFromString(opt->grid);
    world.seed = opt->seed;
    world.calibration = !opt->calibrated;
    if (!opt->mount_shift.empty()) world.digitizer_mount_shift = sim::Vec3(opt->mount_shift[0], opt->mount_shift[1], opt->mount_shift[2]);
    ScanJobOptions job;
    job.calibration_policy = config.calibration;
    job.calibration_dir = calibrationFolder(opt->calibration_dir, config.calibration, opt->runs);
    job.run.limits = config.limits;
    // A replay plays the recording's plan on a cell that serves the recording.
    std::shared_ptr<sim::CellReplay> replay;
    if (!opt->replay.empty()) {
      if (!virtual_cell) throw std::runtime_error("--replay runs on the built-in virtual cell: leave --cell out");
      if (!opt->dry_run) requireUmockdevPreload();  // may run this program again: before the recording is read
      sim::RecordedSession recorded = sim::loadRecordedSession(opt->replay);
      if (const auto loss = stampscan::trace::describeDataLoss(recorded.health); loss && !opt->accept_damaged)
        throw std::runtime_error(opt->replay + " is damaged: " + *loss + "; pass --accept-damaged to replay what remains");
      if (recorded.session.plan_toml.empty() && opt->plan.empty())
        throw std::runtime_error(opt->replay + " does not carry its scan plan (recorded before traces kept it): pass "
                                               "--plan with the plan it was recorded with");
      job.plan = opt->plan.empty() ? acquisition::parseScanPlan(recorded.session.plan_toml, opt->replay + " (its plan)")
                                   : acquisition::loadScanPlan(opt->plan);
      world.part = recorded.session.part == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan;
      job.run.session = recorded.session;
      if (opt->part_id == "sample" && !recorded.session.part_id.empty()) opt->part_id = recorded.session.part_id;
      replay = std::make_shared<sim::CellReplay>(std::move(recorded));
      job.replayed_trace = opt->replay;
    } else {
      job.plan = opt->plan.empty() ? sim::planScan(world) : acquisition::loadScanPlan(opt->plan);
    }
    if (opt->plan.empty() && !replay) {
      if (opt->laser_only)
        std::erase_if(job.plan.steps, [](const acquisition::PlanStep& s) { return std::holds_alternative<acquisition::StereoStep>(s); });
      job.plan.name = job.plan.part.kind + (opt->laser_only ? ", laser" : ", laser and stereo") +
                      (opt->calibrated ? ", on the calibration in use" : ", with calibration scenes");
    }
    if (opt->dry_run) {
      const auto problems = acquisition::checkPlan(job.plan, job.run.limits);
      printDryRun(job.plan, config, job.run.limits, problems);
      return problems.empty() ? 0 : 1;
    }

    // The embedded virtual cell first: hosting may re-execute this program (umockdev).
    std::unique_ptr<HostedVirtualCell> hosted;
    if (virtual_cell) {
      hosted = std::make_unique<HostedVirtualCell>(world, config, replay, job.plan.stereoCount() > 0);
      config = hosted->config();
      if (!replay)
        job.truth = SimulationTruth{sim::groundTruth(hosted->cell().part(), world.grid),
                                    hosted->cell().truth().digitizer_latency_ns};
    }
    acquisition::Cell cell(config);
    job.part_id = opt->part_id;
    job.runs_dir = opt->runs;
    job.results_database = config.results_database;
    job.material = opt->material;
    job.program = opt->program;
    // The cell's geometry as drawn: what calibration starts from. (A real cell's file does not carry
    // it yet; the virtual cell's sensors are the simulator's; a replay's are the recording's.)
    if (!replay) job.run.session = sim::describeSession(world);
    job.run.session.part_id = opt->part_id;
    applySphereCertificate(config.calibration, job.run.session);

    std::printf("station scan: %s on %s%s\n", job.plan.name.c_str(), config.name.c_str(),
                hosted ? " (hosted in this process)" : "");
    TerminalObserver observer(opt->quiet);
    ScanJob scan(cell, &observer);
    ScanJobResult r;
    {
      const StopSignalGuard stop([&](const std::string& reason) { scan.abort(reason); });
      r = scan.run(job);
    }
    std::printf("  measured    %zu grid elements; cloud4d.ply, fitted.ply, mesh.ply (%.2f s after the scan)\n", r.elements,
                r.measure_seconds);
    std::printf("  calibration digitizer: %s; cameras: %s\n", r.digitizer_calibration.c_str(), r.camera_calibration.c_str());
    if (r.accuracy && hosted)
      std::printf("  accuracy    against the simulated part: %zu of %zu elements matched, position RMS %.4f mm, "
                  "thickness strain RMS %.4f; latency %.3f ms (true %.3f)\n",
                  r.accuracy->matched, r.elements, r.accuracy->position_rms_mm, r.accuracy->strain_rms,
                  static_cast<double>(r.digitizer.latency_ns) * 1e-6,
                  static_cast<double>(job.truth->digitizer_latency_ns) * 1e-6);
    if (replay) printReplay(*replay, r);
    if (r.report) {
      std::printf("  verdict     %s: %s (material %s); report.pdf, report.html, fld.png, strain maps (%.1f s)\n",
                  report::toString(r.report->verdict), r.report->verdict_reason.c_str(), r.report->material.c_str(),
                  r.report->seconds);
    }
    std::printf("  results     %s\n", r.run_dir.c_str());
    if (!r.history_error.empty())
      std::fprintf(stderr, "station: warning: the run is complete but not in the results history: %s\n",
                   r.history_error.c_str());
    if (!r.report_error.empty()) {
      std::fprintf(stderr, "station: error: the scan is measured, but its report failed: %s (run `station report %s` "
                           "once the cause is fixed)\n", r.report_error.c_str(), r.run_dir.c_str());
      return 1;
    }
    if (r.data_loss) {
      if (!opt->accept_damaged) {
        std::fprintf(stderr, "station: error: the scan lost data: %s. The results lack those elements (run.json says "
                             "so); scan again, or pass --accept-damaged to accept such a result\n", r.data_loss->c_str());
        return 1;
      }
      std::printf("  accepted    an incomplete scan (--accept-damaged): %s\n", r.data_loss->c_str());
    }
    return 0;
  };
}

}  // namespace stampscan::station
