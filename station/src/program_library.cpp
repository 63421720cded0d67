#include "program_library.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include "virtual_cell/virtual_cell_host.hpp"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <variant>
#include <vector>

namespace stampscan::station {

namespace fs = std::filesystem;

fs::path programLibrary(const acquisition::CellConfig& cell, bool virtual_cell, const fs::path& runs) {
  if (!cell.program_library.empty()) return cell.program_library;
  if (virtual_cell) return runs / "programs";
  throw std::runtime_error(cell.source + ": the cell has no program library ([programs] library): give the "
                           "program's folder, or name the library in the cell file");
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
  // The virtual cell's own parts: sim-<part>-<grid>[-sample].
  if (virtual_cell && !fs::exists(library / name_or_dir / acquisition::kProgramFile, ec)) {
    for (const SimulatedProgramName& simulated : simulatedProgramNames())
      if (name_or_dir == simulated.name) {
        const fs::path dir = library / name_or_dir;
        std::printf("  program     writing the virtual cell's %s with a %s grid%s into %s\n", simulated.part.c_str(),
                    simulated.grid.c_str(), simulated.sample_region ? " (its sample region)" : "", dir.c_str());
        writeSimulatedProgram(simulated, cell, dir);
      }
  }
  const fs::path dir = library / name;
  if (fs::exists(dir / acquisition::kProgramFile, ec)) return acquisition::loadPartProgram(dir);
  return acquisition::loadPartProgram(acquisition::findProgram(library, name));  // its error lists the library
}

std::optional<std::uint16_t> lineNumberOf(const acquisition::PartProgram& program, bool virtual_cell) {
  if (program.line_number || !virtual_cell) return program.line_number;
  // A virtual cell's own part written before programs carried their number keeps its number.
  for (const SimulatedProgramName& simulated : simulatedProgramNames())
    if (simulated.name == program.name) return simulated.line_number;
  return std::nullopt;
}

std::optional<std::string> programByLineNumber(std::uint16_t line_number, const acquisition::CellConfig& cell,
                                               bool virtual_cell, const fs::path& runs) {
  const fs::path library = programLibrary(cell, virtual_cell, runs);
  std::error_code ec;
  if (fs::is_directory(library, ec))
    if (auto name = acquisition::findProgramByLineNumber(library, line_number)) return name;
  if (!virtual_cell) return std::nullopt;
  // The virtual cell's own parts: not yet written (written on first use), or written without a number.
  for (const SimulatedProgramName& simulated : simulatedProgramNames()) {
    if (simulated.line_number != line_number) continue;
    const fs::path file = library / simulated.name / acquisition::kProgramFile;
    if (!fs::exists(file, ec)) return simulated.name;
    std::ifstream in(file, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    try {
      if (!acquisition::parseProgramFile(text.str(), file.string()).line_number) return simulated.name;
    } catch (const acquisition::ProgramError&) {
      // unreadable: the scan would fail on it too; the number names no program
    }
  }
  return std::nullopt;
}

acquisition::ScanPlan programPlan(const acquisition::PartProgram& program, const acquisition::CellConfig& cell,
                                  const acquisition::CalibrationScenes& scenes, bool calibration_scenes) {
  if (!program.hasPlan())
    throw std::runtime_error(program.name + " (" + program.folder.string() +
                             ") has no scan plan yet: make one from its model with `station plan " + program.folder.string() +
                             " --into-program` (or Plan on the panel's scan page)");
  // The program's plan is in the part's datum frame; the cell's fixture puts it on the table.
  acquisition::ScanPlan plan = acquisition::placeOnFixture(program.plan, cell.geometry, cell.limits.index_step);
  if (calibration_scenes) plan = acquisition::withCalibrationScenes(std::move(plan), cell.geometry, cell.limits, scenes);
  return plan;
}

acquisition::ScanPlan generatedPlan(const acquisition::PartProgram& program, const acquisition::CellConfig& cell,
                                    const acquisition::PlannerOptions& options) {
  acquisition::PartSpec part = program.plan.part;
  if (!program.hasPlan()) part.kind = program.simulated_part.empty() ? program.name : program.simulated_part;
  part.grid = program.grid.kind;
  part.pitch = program.grid.pitch_mm;
  part.circle_diameter = program.grid.circle_diameter_mm;
  part.line_width = program.grid.line_width_mm;
  acquisition::ScanPlan plan = acquisition::planPart(program.model, part, cell.geometry, cell.limits, options);
  plan.name = program.name + ", generated from " + program.model_file.string() + " for " + cell.name;
  return plan;
}

fs::path adoptPlan(acquisition::PartProgram program, const acquisition::ScanPlan& plan) {
  const bool had_plan = program.hasPlan();
  if (!had_plan) program.plan_file = "plan.toml";
  const fs::path target = program.folder / program.plan_file;
  if (fs::exists(target)) fs::copy_file(target, target.string() + ".bak", fs::copy_options::overwrite_existing);
  fitting::writeFileAtomically(target, acquisition::toToml(plan));
  if (!had_plan) acquisition::writePartProgram(program, program.folder);
  return target;
}

}  // namespace stampscan::station
