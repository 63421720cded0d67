// `station sim part dome|pan -o DIR`: writes the part program of one of the simulator's parts (its
// program file, nominal model and whole-part plan), the folder a real part number would have.
#include "stampscan/sim/part_model.hpp"
#include "stampscan/station/commands.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

namespace stampscan::station {

namespace {

struct PartOptions {
  std::string part;
  std::string grid = "circle";
  std::string output;
  std::string cell;
  std::string name;
  acquisition::SimulationParameters simulation;
};

std::string kilobytes(const std::filesystem::path& file) {
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(file, ec);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f kB", ec ? 0.0 : static_cast<double>(bytes) / 1e3);
  return buf;
}

}  // namespace

CommandRunner addSimPartSubcommand(CLI::App* sim) {
  auto opt = std::make_shared<PartOptions>();
  CLI::App* cmd = sim->add_subcommand("part", "Write the part program (program, nominal model, plan) of a simulated part");
  cmd->add_option("part", opt->part, "The simulated part: dome or pan")->required()->check(CLI::IsMember({"dome", "pan"}));
  cmd->add_option("--grid", opt->grid, "Printed grid: circle or square (2.54 mm)")->check(CLI::IsMember({"circle", "square"}));
  cmd->add_option("-o,--output", opt->output, "The program's folder (created if missing)")->required();
  cmd->add_option("--cell", opt->cell, "The cell the plan is made for (its sensors, head and artefacts); default: the "
                                       "built-in virtual cell");
  cmd->add_option("--name", opt->name, "The program's name, its part number (default: sim-PART-GRID)");
  cmd->add_option("--scale", opt->simulation.scale, "The part's size against the family's own")
      ->check(CLI::Range(0.5, 2.0))
      ->default_val(1.0);
  cmd->add_option("--depth", opt->simulation.depth_mm, "How deep it is drawn, mm (default: the family's, scaled)")
      ->check(CLI::Range(0.1, 60.0));
  cmd->add_option("--peak-strain", opt->simulation.peak_strain,
                  "Its largest major true strain: the dome's pole, the pan's wall band (default: the family's)")
      ->check(CLI::Range(0.01, 0.5));
  return [opt]() {
    const sim::PartKind kind = opt->part == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan;
    const std::filesystem::path dir(opt->output);
    const acquisition::CellConfig cell = opt->cell.empty() ? acquisition::virtualCell() : acquisition::loadCellConfig(opt->cell);
    sim::SimulatedProgramOptions options;
    options.cell = &cell;
    options.simulation = opt->simulation;
    options.name = opt->name;
    sim::writeSimulatedProgram(kind, sim::gridKindFromString(opt->grid), dir, options);
    // Read back as the cell will read it: what is printed is what the folder holds (the STEP
    // model's own tessellation, not the samples its surface was fitted to).
    const acquisition::PartProgram p = acquisition::loadPartProgram(dir);
    const acquisition::Box3 box = p.model.bounds();
    std::printf("station sim part: %s, the simulated %s with a %s grid\n", p.name.c_str(), opt->part.c_str(), opt->grid.c_str());
    std::printf("  part        %s\n", p.description.c_str());
    std::printf("  program     %s\n", (dir / acquisition::kProgramFile).string().c_str());
    std::printf("  model       %s: %s, %zu triangles, %.0f x %.0f x %.1f mm\n", (dir / p.model_file).string().c_str(),
                kilobytes(dir / p.model_file).c_str(), p.model.triangles.size(), box.max[0] - box.min[0],
                box.max[1] - box.min[1], box.max[2] - box.min[2]);
    std::printf("  plan        %s: %zu laser sweeps, %zu stereo poses\n", (dir / p.plan_file).string().c_str(),
                p.plan.sweepCount(), p.plan.stereoCount());
    return 0;
  };
}

}  // namespace stampscan::station
