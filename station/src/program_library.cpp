#include "program_library.hpp"

#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/part_model.hpp"

#include <cstdio>
#include <stdexcept>

namespace stampscan::station {

namespace fs = std::filesystem;

fs::path programLibrary(const acquisition::CellConfig& cell, bool virtual_cell, const fs::path& runs) {
  if (!cell.program_library.empty()) return cell.program_library;
  if (virtual_cell) return runs / "programs";
  throw std::runtime_error(cell.source + ": the cell has no program library ([programs] library): give the "
                           "program's folder, or name the library in the cell file");
}

std::vector<std::string> simulatedProgramNames() {
  return {"sim-dome-circle", "sim-dome-square", "sim-pan-circle", "sim-pan-square"};
}

acquisition::PartProgram programToScan(const std::string& name_or_dir, const acquisition::CellConfig& cell,
                                       bool virtual_cell, const fs::path& runs) {
  std::error_code ec;
  const bool folder = fs::is_directory(name_or_dir, ec) || fs::path(name_or_dir).filename() == acquisition::kProgramFile;
  if (folder) return acquisition::loadPartProgram(name_or_dir);
  return programFromLibrary(name_or_dir, cell, virtual_cell, runs);
}

acquisition::PartProgram programFromLibrary(const std::string& name, const acquisition::CellConfig& cell,
                                            bool virtual_cell, const fs::path& runs) {
  if (name.empty() || name.find('/') != std::string::npos || name.front() == '.')
    throw std::runtime_error("'" + name + "' is not a program's name");
  std::error_code ec;
  const std::string& name_or_dir = name;
  const fs::path library = programLibrary(cell, virtual_cell, runs);
  // The virtual cell's own parts: sim-<part>-<grid>.
  if (virtual_cell && !fs::exists(library / name_or_dir / acquisition::kProgramFile, ec)) {
    for (const char* part : {"dome", "pan"})
      for (const char* grid : {"circle", "square"})
        if (name_or_dir == std::string("sim-") + part + "-" + grid) {
          sim::SimulatedProgramOptions options;
          options.cell = &cell;
          const fs::path dir = library / name_or_dir;
          std::printf("  program     writing the virtual cell's %s with a %s grid into %s\n", part, grid, dir.c_str());
          sim::writeSimulatedProgram(std::string(part) == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan,
                                     sim::gridKindFromString(grid), dir, options);
        }
  }
  const fs::path dir = library / name;
  if (fs::exists(dir / acquisition::kProgramFile, ec)) return acquisition::loadPartProgram(dir);
  return acquisition::loadPartProgram(acquisition::findProgram(library, name));  // its error lists the library
}

acquisition::ScanPlan programPlan(const acquisition::PartProgram& program, const acquisition::CellConfig& cell,
                                  const acquisition::CalibrationScenes& scenes, bool calibration_scenes) {
  acquisition::ScanPlan plan = program.plan;
  if (calibration_scenes) {
    acquisition::ScanPlan calibration = acquisition::calibrationPlan(cell, scenes);
    calibration.steps.insert(calibration.steps.end(), plan.steps.begin(), plan.steps.end());
    plan.steps = std::move(calibration.steps);
  }
  return plan;
}

}  // namespace stampscan::station
