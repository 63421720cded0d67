// `station plan PROGRAM`: a scan plan from the part program's nominal model for the cell's sensors
// (acquisition/part_planner.hpp), with what it is predicted to see, its motion time against a lower
// bound, and the same figures for the program's own plan beside it. Writes the plan file with -o, or
// into the program with --into-program (the program's plan file replaced, the old one kept as .bak).
#include "program_library.hpp"
#include "cell_choice.hpp"

#include "stampscan/acquisition/part_planner.hpp"
#include "stampscan/acquisition/plan_collisions.hpp"
#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/station/commands.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

namespace stampscan::station {

namespace fs = std::filesystem;

namespace {

struct PlanOptions {
  CellChoice cell;
  std::string program, output, runs = "stampscan-runs";
  bool into_program = false, laser_only = false;
  acquisition::PlannerOptions planner;
};

struct PlanFigures {
  acquisition::Coverage coverage;
  double motion_s = 0;
  double laser_motion_s = 0;  // the laser passes alone (from the park, back to it)
  double sweeping_s = 0;      // of which sweeping
  std::size_t collisions = 0;
  std::size_t sweeps = 0, views = 0;
  std::vector<std::string> problems;  // against the cell's travel and head, and the head's body against the part
};

// `placed_model`: the program's model on the cell's fixture, where the placed plan runs.
PlanFigures figuresOf(const acquisition::ScanPlan& plan, const acquisition::PartProgram& program,
                      const acquisition::NominalModel& placed_model, const acquisition::CellConfig& cell,
                      double spacing) {
  PlanFigures f;
  acquisition::CoverageOptions coverage;
  coverage.sample_spacing_mm = spacing;
  f.coverage = acquisition::predictCoverage(program.model, plan, cell.geometry, cell.limits, coverage);
  const acquisition::ScanPlan placed = acquisition::placeOnFixture(plan, cell.geometry, cell.limits.index_step);
  f.motion_s = acquisition::motionSeconds(placed, cell.limits);
  acquisition::ScanPlan laser_only = placed;
  std::erase_if(laser_only.steps, [](const acquisition::PlanStep& step) {
    return std::holds_alternative<acquisition::StereoStep>(step);
  });
  f.laser_motion_s = acquisition::motionSeconds(laser_only, cell.limits);
  f.sweeping_s = acquisition::sweepingSeconds(laser_only, cell.limits);
  f.problems = acquisition::checkPlan(placed, cell.limits);
  const acquisition::CollisionOptions clearance;
  for (const acquisition::PlanCollision& c :
       acquisition::checkCollisions(placed_model, cell.geometry.fixture.body, acquisition::toRigidPose(cell.geometry.fixture.datum),
                                    placed, cell.geometry.head, clearance)) {
    f.problems.push_back(acquisition::describe(c, placed, clearance.clearance_mm));
    ++f.collisions;
  }
  f.sweeps = plan.sweepCount(acquisition::Scene::Part);
  f.views = plan.stereoCount(acquisition::Scene::Part);
  return f;
}

void printFigures(const char* label, const PlanFigures& f) {
  const acquisition::Coverage& c = f.coverage;
  std::printf("  %-10s %zu laser passes, %zu stereo views; seen: laser %.1f %%, stereo %.1f %%, either %.1f %% of the "
              "grid area; overlap %.1f %% of the laser's; motion %.1f s\n",
              label, f.sweeps, f.views, 100 * c.share(c.laser_area), 100 * c.share(c.stereo_area),
              100 * c.share(c.either_area), c.laser_area > 0 ? 100 * c.overlap_area / c.laser_area : 0.0, f.motion_s);
  for (const std::string& p : f.problems) std::printf("  %-10s cannot run on this cell: %s\n", "", p.c_str());
}

// Where the grid area is not seen: how much, and the box the unseen samples lie in, so that an
// engineer can find them on the model (a deep pocket, an undercut).
void printUnseen(const acquisition::Coverage& c) {
  double unseen = 0;
  std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    if (c.laser_passes[i] > 0 || c.stereo[i]) continue;
    unseen += c.sample_area[i];
    for (int k = 0; k < 3; ++k) {
      lo[static_cast<std::size_t>(k)] = std::min(lo[static_cast<std::size_t>(k)], c.points[i][static_cast<std::size_t>(k)]);
      hi[static_cast<std::size_t>(k)] = std::max(hi[static_cast<std::size_t>(k)], c.points[i][static_cast<std::size_t>(k)]);
    }
  }
  if (unseen <= 0) {
    std::printf("  unseen     none of the grid area\n");
    return;
  }
  std::printf("  unseen     %.0f mm^2 (%.2f %%) of the grid area, within x %.1f .. %.1f, y %.1f .. %.1f, z %.1f .. %.1f mm "
              "(datum frame)\n",
              unseen, 100 * c.share(unseen), lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
}

}  // namespace

CommandRunner addPlanCommand(CLI::App& app) {
  auto opt = std::make_shared<PlanOptions>();
  CLI::App* cmd = app.add_subcommand(
      "plan", "A scan plan from a part program's nominal model for the cell's sensors: laser passes and stereo views, "
              "what they are predicted to see, the motion time against a lower bound, and the program's own plan beside it");
  cmd->add_option("program", opt->program,
                  "The part program: its name in the cell's program library, or its folder")
      ->required();
  opt->cell.addTo(cmd);
  cmd->add_option("-o,--output", opt->output, "Write the plan file here (TOML, the part's datum frame)");
  cmd->add_flag("--into-program", opt->into_program,
                "Make the plan the program's own: its plan file is replaced (the old one kept beside it as .bak)");
  cmd->add_option("--runs", opt->runs, "Folder of run folders (a virtual cell's program library is RUNS/programs)");
  cmd->add_flag("--laser-only", opt->laser_only, "Plan laser passes only");
  cmd->add_option("--overlap", opt->planner.strip_overlap, "The share of a pass's fan that overlaps its neighbour's (less where that saves passes, never less than keeps every element whole within one stripe)")
      ->check(CLI::Range(0.0, 0.85));
  cmd->add_option("--profile-spacing", opt->planner.profile_spacing_mm,
                  "mm the head moves between two profiles while sweeping; the sweep speed is this times the digitizer's profile rate")
      ->check(CLI::Range(0.005, 1.0));
  cmd->add_option("--sweep-speed", opt->planner.sweep_speed, "mm/s while the digitizer scans (instead of the one from the profile spacing)")
      ->check(CLI::Range(1.0, 500.0));
  cmd->add_option("--stereo-rows", opt->planner.stereo_rows, "Rows of stereo views")->check(CLI::Range(0, 20));
  cmd->add_option("--stereo-columns", opt->planner.stereo_columns, "Columns of stereo views")->check(CLI::Range(0, 20));
  cmd->add_option("--spacing", opt->planner.sample_spacing_mm, "mm between the samples of the grid area")
      ->check(CLI::Range(0.2, 20.0));
  return [opt]() {
    const acquisition::CellConfig cell = opt->cell.load();
    acquisition::PartProgram program = programToScan(opt->program, cell, opt->cell.hosted(), opt->runs);
    acquisition::PlannerOptions planner = opt->planner;
    if (opt->laser_only) planner.stereo = false;
    const acquisition::ScanPlan plan = generatedPlan(program, cell, planner);

    const acquisition::NominalModel placed_model = acquisition::placeOnFixture(program.model, cell.geometry);
    const PlanFigures generated = figuresOf(plan, program, placed_model, cell, planner.sample_spacing_mm);
    const std::optional<PlanFigures> own =
        program.hasPlan() ? std::optional(figuresOf(program.plan, program, placed_model, cell, planner.sample_spacing_mm))
                          : std::nullopt;
    const double sweep_speed = acquisition::sweepSpeed(planner, cell.geometry, cell.limits);
    const double bound = acquisition::scanTimeLowerBound(generated.coverage.grid_area, cell.geometry, sweep_speed);
    std::printf("plan %s on %s: grid area %.0f mm^2 (facets facing the sensors), sampled every %.1f mm\n",
                program.name.c_str(), cell.name.c_str(), generated.coverage.grid_area, planner.sample_spacing_mm);
    printFigures("generated", generated);
    if (own) printFigures("program's", *own);
    else std::printf("  program's  none yet (write the generated one into the program with --into-program)\n");
    const double floor = acquisition::scanTimeFloor(generated.coverage.grid_area, cell.geometry, sweep_speed);
    // The bound is the sweeping bound plus the head's moves: each plan against the bound
    // plus its own moves, and its sweeping alone against the bound and the floor.
    const auto ratios = [&](const PlanFigures& f) {
      const double moves = f.laser_motion_s - f.sweeping_s;
      char text[200];
      std::snprintf(text, sizeof text, "%.1f s (sweeping %.1f s + moving %.1f s) = %.2f x the bound with those moves; sweeping %.2f x the bound, %.2f x the floor",
                    f.laser_motion_s, f.sweeping_s, moves, bound > 0 ? f.laser_motion_s / (bound + moves) : 0.0,
                    bound > 0 ? f.sweeping_s / bound : 0.0, floor > 0 ? f.sweeping_s / floor : 0.0);
      return std::string(text);
    };
    std::printf("  bound      sweeping the grid area takes at least %.1f s (area / (stripe at the standoff x %.0f mm/s); "
                "%.1f s, the floor, with the stripe at the far end of the range)\n",
                bound, sweep_speed, floor);
    std::printf("  passes     generated: %s\n", ratios(generated).c_str());
    if (own) std::printf("             program's: %s\n", ratios(*own).c_str());
    printUnseen(generated.coverage);
    if (generated.collisions == 0)
      std::printf("  clearance  the head's body (%zu solids of the cell file) keeps %.0f mm from the part and the fixture "
                  "(%zu solids of the cell file) along every pass and move of the generated plan\n",
                  cell.geometry.head.body.size(), acquisition::CollisionOptions{}.clearance_mm, cell.geometry.fixture.body.size());
    if (!opt->output.empty()) {
      fs::create_directories(fs::absolute(opt->output).parent_path());
      fitting::writeFileAtomically(opt->output, acquisition::toToml(plan));
      std::printf("  written    %s\n", opt->output.c_str());
    }
    if (opt->into_program) {
      const bool had_plan = program.hasPlan();
      const fs::path target = adoptPlan(program, plan);
      std::printf("  written    %s (the program's plan%s)\n", target.c_str(),
                  had_plan ? ("; the old one is " + target.string() + ".bak").c_str() : ", named in its program file now");
    }
    return generated.problems.empty() ? 0 : 1;
  };
}

}  // namespace stampscan::station
