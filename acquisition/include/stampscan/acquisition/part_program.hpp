// A part program: everything the cell knows of one part number, as one folder.
//
//   DIR/program.toml   the program file (below)
//   DIR/model.stl      the nominal formed part in the part's datum frame, mm (.stl, or .step/.stp)
//   DIR/plan.toml      the scan plan (scan_plan.hpp's plan file), once the part is planned
//
// program.toml:
//
//   name = "pan-4711"             # the part number; required
//   description = "..."           # optional
//   model = "model.stl"           # required, relative to the folder
//   plan = "plan.toml"            # relative to the folder; absent: not planned yet (`station plan
//                                 # PROGRAM --into-program`, or the panel, makes one from the model)
//   press_program = "..."         # optional: the press program that forms it
//   line_number = 12              # optional, 1 .. 65535: the number the line's PLC starts it by
//   [grid]                        # the grid printed on the blank; required
//   kind = "circle"               # circle or square
//   pitch_mm = 2.54
//   circle_diameter_mm = 2.54     # required for a circle grid
//   line_width_mm = 0.15
//   [sheet]                       # required
//   material = "DC04"
//   thickness_mm = 0.8
//   [[region]]                    # optional, any number: regions of interest, datum frame
//   name = "corner"
//   min_mm = [-80, -60]
//   max_mm = [-40, -20]
//   [simulation]                  # optional: read by the virtual cell only
//   part = "pan"                  # which of the simulator's part families this is: dome or pan
//   scale = 1.0                   # optional: its size against the family's own, 0.5 .. 2
//   depth_mm = 20                 # optional: how deep it is drawn (default: the family's, scaled)
//   peak_strain = 0.3             # optional: its largest major true strain, up to 0.5 (default: the family's)
//
// Every value is checked when read; unknown keys are refused (a misspelt key would otherwise be
// ignored). Errors throw ProgramError with one line naming the file, the section and the key:
// "parts/pan-4711/program.toml: [grid] pitch_mm must be a positive number". The plan's and the
// model's own errors name their files.
//
// Thread safety: the functions share nothing; STEP models are read through Open CASCADE (see
// nominal_model.hpp).
#pragma once

#include "stampscan/acquisition/nominal_model.hpp"
#include "stampscan/acquisition/scan_plan.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::acquisition {

class ProgramError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr const char* kProgramFile = "program.toml";

// The grid printed on the blank before forming.
struct PrintedGrid {
  std::string kind = "circle";     // circle or square
  double pitch_mm = 2.54;
  double circle_diameter_mm = 2.54;
  double line_width_mm = 0.15;
  bool operator==(const PrintedGrid&) const = default;
};

// A region of interest: an axis-aligned rectangle of the datum frame's xy plane.
struct RegionOfInterest {
  std::string name;
  std::array<double, 2> min_mm{0, 0}, max_mm{0, 0};
  bool operator==(const RegionOfInterest&) const = default;
};

// The parameters of a simulated part ([simulation]); 0 is the family's own value.
struct SimulationParameters {
  double scale = 1;        // lengths against the family's own
  double depth_mm = 0;     // the dome's pole or the pan's pocket below (above) its flange
  double peak_strain = 0;  // the dome's pole strain, the pan's wall band strain
  bool operator==(const SimulationParameters&) const = default;
};

struct PartProgram {
  std::string name;         // the part number
  std::string description;
  std::filesystem::path folder;      // the program's folder
  std::filesystem::path model_file;  // as written in program.toml: relative to the folder
  std::filesystem::path plan_file;   // likewise; empty: the program has no plan yet
  PrintedGrid grid;
  std::string material;
  double sheet_thickness_mm = 0;
  std::string press_program;
  // The number the line's PLC names it by (line_program_number, drivers/plc/REGISTER_MAP.md); none:
  // the line cannot start it. Unique within a library (findProgramByLineNumber checks).
  std::optional<std::uint16_t> line_number;
  std::vector<RegionOfInterest> regions;
  std::string simulated_part;  // "dome" or "pan" when the virtual cell is to simulate it; "" when none
  SimulationParameters simulation;
  ScanPlan plan;  // no steps when the program has no plan yet
  NominalModel model;
  bool hasPlan() const { return !plan_file.empty(); }
};

// The program file alone (model and plan not read): `source_name` prefixes the errors.
PartProgram parseProgramFile(const std::string& toml_text, const std::string& source_name);

// Reads a program: a folder holding program.toml, or the program.toml itself; then its plan and its
// model. Checks that they agree: the plan's [part] grid is the program's [grid], and a simulated
// part's plan is for that part. Throws ProgramError, PlanError or ModelError, each naming its file.
PartProgram loadPartProgram(const std::filesystem::path& dir_or_program_file);

// The problems of a program whose plan and grid disagree, one line each; empty when they agree.
std::vector<std::string> checkConsistency(const PartProgram& program);

// The program file's text (parseProgramFile reads it back equal).
std::string toToml(const PartProgram& program);

// Writes program.toml into `dir` (created if missing), atomically: the file appears whole or not at
// all. The model and plan files are not written (writeStl, writeStepSurface, toToml(ScanPlan)).
void writePartProgram(const PartProgram& program, const std::filesystem::path& dir);

// The folders of a program library that hold a program.toml, sorted by path.
std::vector<std::filesystem::path> listPrograms(const std::filesystem::path& library);

// The name of the library's program whose line_number is `number` (program files only are read; one
// that does not read is passed over); nothing when none has it. Throws ProgramError when two
// programs share it, or the library is not a folder.
std::optional<std::string> findProgramByLineNumber(const std::filesystem::path& library, std::uint16_t number);

// A program's folder: `name_or_dir` when it is a folder holding program.toml (or that file),
// otherwise the library's program whose name is `name_or_dir`. Throws ProgramError listing the
// library's programs when there is none.
std::filesystem::path findProgram(const std::filesystem::path& library, const std::string& name_or_dir);

}  // namespace stampscan::acquisition
