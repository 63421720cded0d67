// The simulator's parts as part programs: the nominal model of a formed part (its height field,
// tessellated over its footprint), and whole program folders for the built-in parts, so that the
// virtual cell's parts are described the way a real part number is (acquisition/part_program.hpp).
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/nominal_model.hpp"
#include "stampscan/acquisition/part_program.hpp"
#include "stampscan/sim/formed_part.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <filesystem>
#include <cstdint>
#include <optional>
#include <string>

namespace stampscan::sim {

// The part's height sampled on a regular grid over its footprint, edges included, at about
// `spacing_mm` (the footprint is divided into whole cells no wider than that).
acquisition::HeightGrid sampleHeights(const FormedPart& part, double spacing_mm = 0.5);

// The part's nominal model: the sampled heights as triangles, two per cell. The formed part's
// machine frame is its datum frame. At 0.5 mm spacing the mesh is within about 0.02 mm (vertically)
// of the true surface of either built-in part (tests/sim/test_part_model.cpp).
acquisition::NominalModel partModel(const FormedPart& part, double spacing_mm = 0.5);

struct SimulatedProgramOptions {
  double mesh_spacing_mm = 0.5;  // the STL model's (pan)
  double step_spacing_mm = 1.0;  // the heights the STEP surface is fitted to (dome)
  double step_tolerance_mm = 0.005;
  std::string material = "DC04";
  double sheet_thickness_mm = 0.8;
  // The cell the plan is made for (its sensors, head and artefacts); null: the built-in virtual cell.
  const acquisition::CellConfig* cell = nullptr;
  // The plan covers only the quick sessions' sample region of the part (ScanParams::quick(): 40 x
  // 30 mm, two stereo views), and the program is named sim-<part>-<grid>-sample.
  bool sample_region = false;
  // The part family's parameters (scale, depth, strain level); the defaults are the family's own.
  acquisition::SimulationParameters simulation;
  std::string name;  // the program's name (its part number); "": simulatedProgramName's
  std::optional<std::uint16_t> line_number;  // the number the line's PLC starts it by; none: none
};

// The world's part with a program's family parameters applied: lengths scaled, and its depth and
// peak strain when given (0 keeps the family's own, scaled).
void applySimulation(ScanParams& world, const acquisition::SimulationParameters& parameters);

// The virtual world that simulates a program's part: the family and parameters of its [simulation]
// section and its printed grid, on `world`'s cell. Throws std::runtime_error naming the program's
// folder when it gives no simulated part.
ScanParams worldForProgram(ScanParams world, const acquisition::PartProgram& program);

// The name of a simulated part's program: sim-<part>-<grid>, with -sample for the sample region.
std::string simulatedProgramName(PartKind part, GridKind grid, bool sample_region = false);

// Writes a complete program folder for a built-in part: plan.toml, the whole part's plan generated
// from its nominal model for the cell (acquisition::planPart, as `station plan` makes one for any
// part), or the simulator's plan of its sample region (sim::planScan; laser and stereo, no
// calibration scenes either way); the model, the dome as STEP (one
// B-spline face approximating its height field), the pan as binary STL; and program.toml last, with
// [simulation] part, so that a folder holding program.toml is complete. Every file is written
// atomically. Returns the program as written; its model is the mesh written (pan), or the sampled
// heights the STEP surface approximates (dome), not the file read back.
acquisition::PartProgram writeSimulatedProgram(PartKind part, GridKind grid, const std::filesystem::path& dir,
                                               const SimulatedProgramOptions& options = {});

}  // namespace stampscan::sim
