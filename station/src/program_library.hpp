// The part programs a command scans: the cell's program library, a program found in it (or given by
// its folder), and the plan a scan of it runs. On a virtual cell the library also holds the
// simulator's own parts as programs, written there the first time they are asked for.
#pragma once

#include "stampscan/acquisition/calibration_plan.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/part_planner.hpp"
#include "stampscan/acquisition/part_program.hpp"
#include "virtual_cell/virtual_cell_host.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::station {

// The cell file's [programs] library; for a virtual cell without one, RUNS/programs.
std::filesystem::path programLibrary(const acquisition::CellConfig& cell, bool virtual_cell,
                                     const std::filesystem::path& runs);

// The program `name_or_dir` names (a folder, or a name in the library), read and checked. On a
// virtual cell a simulated part's program (sim-dome-circle, sim-pan-square, ...) missing from the
// library is first written there, its plan made for this cell. Throws naming what is wrong.
acquisition::PartProgram programToScan(const std::string& name_or_dir, const acquisition::CellConfig& cell,
                                       bool virtual_cell, const std::filesystem::path& runs);

// A program of the library by its name alone (never a path: the panel's requests); on a virtual cell
// its own simulated parts' programs are written on first use, as above.
acquisition::PartProgram programFromLibrary(const std::string& name, const acquisition::CellConfig& cell,
                                            bool virtual_cell, const std::filesystem::path& runs);

// The name of the library's program the line's PLC starts by `line_number`; nothing when none has
// it. On a virtual cell its own simulated parts have the numbers of simulatedProgramNames() where
// the library has no program of their name. Throws naming what is wrong (two programs with one number).
std::optional<std::string> programByLineNumber(std::uint16_t line_number, const acquisition::CellConfig& cell,
                                               bool virtual_cell, const std::filesystem::path& runs);

// The number the line's PLC starts the program by: its own line_number; on a virtual cell, its own
// simulated parts' number (simulatedProgramNames) when their program was written without one.
std::optional<std::uint16_t> lineNumberOf(const acquisition::PartProgram& program, bool virtual_cell);

// The plan a scan of the program runs: its own, carried from the part's datum frame onto the cell's
// fixture (acquisition::placeOnFixture), after the cell's calibration scenes (the reference sphere's
// sweeps and the plate's views, planned for the cell's artefacts) when asked for. Throws naming the
// way to make one when the program has no plan yet.
acquisition::ScanPlan programPlan(const acquisition::PartProgram& program, const acquisition::CellConfig& cell,
                                  const acquisition::CalibrationScenes& scenes, bool calibration_scenes);

// A plan generated from the program's nominal model for the cell's sensors (acquisition::planPart),
// for the program's printed grid; in the part's datum frame, like the program's own.
acquisition::ScanPlan generatedPlan(const acquisition::PartProgram& program, const acquisition::CellConfig& cell,
                                    const acquisition::PlannerOptions& options = {});

// The plan becomes the program's own: its plan file is replaced (the old one kept beside it as
// .bak); a program without a plan gets plan.toml, and its program file names it from then on.
// Returns the plan file written.
std::filesystem::path adoptPlan(acquisition::PartProgram program, const acquisition::ScanPlan& plan);

}  // namespace stampscan::station
