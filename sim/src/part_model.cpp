#include "stampscan/sim/part_model.hpp"

#include "stampscan/acquisition/part_planner.hpp"

#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace stampscan::sim {

namespace fs = std::filesystem;

acquisition::HeightGrid sampleHeights(const FormedPart& part, double spacing_mm) {
  if (!(spacing_mm > 0)) throw std::invalid_argument("sampleHeights: the spacing must be positive");
  const BlankRect box = part.footprint();
  const Vec2 size = box.max - box.min;
  acquisition::HeightGrid grid;
  grid.columns = static_cast<std::size_t>(std::ceil(size.x() / spacing_mm)) + 1;
  grid.rows = static_cast<std::size_t>(std::ceil(size.y() / spacing_mm)) + 1;
  grid.x0 = box.min.x();
  grid.y0 = box.min.y();
  grid.dx = size.x() / static_cast<double>(grid.columns - 1);
  grid.dy = size.y() / static_cast<double>(grid.rows - 1);
  grid.heights.resize(grid.columns * grid.rows);
  for (std::size_t j = 0; j < grid.rows; ++j)
    for (std::size_t i = 0; i < grid.columns; ++i)
      grid.heights[j * grid.columns + i] =
          part.height(grid.x0 + static_cast<double>(i) * grid.dx, grid.y0 + static_cast<double>(j) * grid.dy);
  return grid;
}

acquisition::NominalModel partModel(const FormedPart& part, double spacing_mm) {
  acquisition::NominalModel model = acquisition::meshHeightGrid(sampleHeights(part, spacing_mm));
  model.source = "simulated " + part.name();
  return model;
}

std::string simulatedProgramName(PartKind part, GridKind grid, bool sample_region) {
  return std::string("sim-") + (part == PartKind::Dome ? "dome" : "pan") + "-" + toString(grid) +
         (sample_region ? "-sample" : "");
}

void applySimulation(ScanParams& world, const acquisition::SimulationParameters& parameters) {
  const double s = parameters.scale;
  DomeParams& dome = world.dome;
  dome.blank_half_size *= s;
  dome.die_radius *= s;
  dome.depth = parameters.depth_mm > 0 ? parameters.depth_mm : dome.depth * s;
  if (parameters.peak_strain > 0) dome.pole_strain = parameters.peak_strain;
  StampedPanParams& pan = world.pan;
  for (double* length : {&pan.half_length, &pan.half_width, &pan.pocket_a, &pan.pocket_b, &pan.wall_width,
                         &pan.dome_radius, &pan.dome_height})
    *length *= s;
  pan.depth = parameters.depth_mm > 0 ? parameters.depth_mm : pan.depth * s;
  if (parameters.peak_strain > 0) pan.peak_strain = parameters.peak_strain;
}

ScanParams worldForProgram(ScanParams world, const acquisition::PartProgram& program) {
  if (program.simulated_part.empty())
    throw std::runtime_error(program.folder.string() + ": the virtual cell simulates only its own part families, and "
                             "this program gives none ([simulation] part)");
  world.part = program.simulated_part == "dome" ? PartKind::Dome : PartKind::Pan;
  world.grid.kind = gridKindFromString(program.grid.kind);
  world.grid.pitch = program.grid.pitch_mm;
  world.grid.circle_diameter = program.grid.circle_diameter_mm;
  world.grid.line_width = program.grid.line_width_mm;
  applySimulation(world, program.simulation);
  return world;
}

acquisition::PartProgram writeSimulatedProgram(PartKind kind, GridKind grid, const fs::path& dir,
                                               const SimulatedProgramOptions& options) {
  ScanParams params;
  if (options.cell != nullptr) params.setCell(*options.cell);
  params.part = kind;
  params.grid.kind = grid;
  params.calibration = false;
  params.laser = params.stereo = true;
  if (options.sample_region) {
    const ScanParams quick = ScanParams::quick();
    params.scan_region = quick.scan_region;
    params.stereo_rows = quick.stereo_rows;
    params.stereo_columns = quick.stereo_columns;
  }
  applySimulation(params, options.simulation);
  const std::unique_ptr<FormedPart> part = makePart(params);

  acquisition::PartProgram program;
  program.name = options.name.empty() ? simulatedProgramName(kind, grid, options.sample_region) : options.name;
  program.line_number = options.line_number;
  program.simulation = options.simulation;
  program.folder = dir;
  program.simulated_part = part->name();
  program.grid = {toString(grid), params.grid.pitch, params.grid.circle_diameter, params.grid.line_width};
  program.material = options.material;
  program.sheet_thickness_mm = options.sheet_thickness_mm;
  program.plan_file = "plan.toml";
  program.plan = planScan(params);  // the sample region's; a whole part's is generated below, from its model
  if (kind == PartKind::Dome) {
    program.description = "The simulator's punch-stretched dome (" + toString(grid) + " grid), nominal model a STEP B-spline surface";
    if (options.sample_region) program.description += "; the plan scans its sample region";
    const double r = params.dome.die_radius / 4;
    program.regions.push_back({"pole", {-r, -r}, {r, r}});
  } else {
    program.description = "The simulator's stamped pan (" + toString(grid) + " grid), nominal model a binary STL mesh";
    if (options.sample_region) program.description += "; the plan scans its sample region";
    program.regions.push_back({"pocket", {-params.pan.pocket_a, -params.pan.pocket_b}, {params.pan.pocket_a, params.pan.pocket_b}});
  }

  if (options.simulation != acquisition::SimulationParameters{}) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "; scale %g, depth %g mm, peak strain %g", options.simulation.scale,
                  kind == PartKind::Dome ? params.dome.depth : params.pan.depth,
                  kind == PartKind::Dome ? params.dome.pole_strain : params.pan.peak_strain);
    program.description += buf;
  }

  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot create the program folder: " + ec.message());
  if (kind == PartKind::Dome) {
    program.model_file = "model.step";
    const acquisition::HeightGrid heights = sampleHeights(*part, options.step_spacing_mm);
    acquisition::writeStepSurface(heights, dir / program.model_file, {options.step_tolerance_mm});
    program.model = acquisition::meshHeightGrid(heights);
  } else {
    program.model_file = "model.stl";
    program.model = partModel(*part, options.mesh_spacing_mm);
    acquisition::writeStl(program.model, dir / program.model_file, true);
  }
  program.model.source = (dir / program.model_file).string();
  if (!options.sample_region) {
    // As an engineer teaching a new part would: planned from its nominal model for the cell
    // (acquisition::planPart), for its printed grid.
    const acquisition::CellConfig cell = options.cell != nullptr ? *options.cell : acquisition::virtualCell();
    const acquisition::PartSpec spec = program.plan.part;
    program.plan = acquisition::planPart(program.model, spec, cell.geometry, cell.limits);
    program.plan.name = program.name + ", generated from its nominal model for " + cell.name;
  }
  fitting::writeFileAtomically(dir / program.plan_file, acquisition::toToml(program.plan));
  acquisition::writePartProgram(program, dir);  // last: the folder is a program only once it is whole
  return program;
}

}  // namespace stampscan::sim
