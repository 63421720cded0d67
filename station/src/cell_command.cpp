// `station cell check CELL.toml`: reads a cell file as the station would, refuses it with the place
// of its first mistake, or prints the whole cell as understood (every section, every key, those the
// file left out marked as defaults) with the plan limits and the sensors it implies.
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/station/commands.hpp"

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

namespace stampscan::station {

namespace {

struct CellCheckOptions {
  std::string file;
  bool quiet = false;
};

// A few figures a cell's integrator checks the drawing against.
void printSummary(const acquisition::CellConfig& c) {
  const acquisition::CellGeometry& g = c.geometry;
  const trace::CameraIntrinsicsRecord k = acquisition::nominalIntrinsics(g.cameras);
  const double stripe = acquisition::stripeWidth(g.digitizer);
  const double view_w = g.cameras.convergence_mm * g.cameras.width / k.fx, view_h = g.cameras.convergence_mm * g.cameras.height / k.fy;
  std::printf("# %s: %s head%s; the laser's stripe %.1f mm wide at its standoff, %.3f mm between points; the "
              "cameras see %.0f x %.0f mm at %.0f mm (%.3f mm per pixel); %zu solids of the head's body; %zu keys "
              "from defaults\n",
              c.name.c_str(), acquisition::toString(g.head.kind),
              g.head.kind == acquisition::HeadDescription::Kind::Indexing
                  ? (" (every " + std::to_string(g.head.index_step_deg).substr(0, 4) + " deg)").c_str()
                  : "",
              stripe, stripe / (g.digitizer.points_per_profile - 1), view_w, view_h, g.cameras.convergence_mm,
              g.cameras.convergence_mm / k.fx, g.head.body.size(), c.defaulted.size());
}

}  // namespace

CommandRunner addCellCommand(CLI::App& app) {
  auto opt = std::make_shared<CellCheckOptions>();
  CLI::App* cmd = app.add_subcommand("cell", "The cell file: check one and print the cell as understood");
  cmd->require_subcommand(1);
  CLI::App* check = cmd->add_subcommand(
      "check", "Read a cell file as the station does; print the whole cell (every key, defaults marked) or the "
               "first mistake, naming its section and key (exit 1)");
  check->add_option("file", opt->file, "The cell file (TOML); default: the built-in virtual cell");
  check->add_flag("-q,--quiet", opt->quiet, "Print nothing when the file is good");
  return [opt]() {
    const acquisition::CellConfig cell =
        opt->file.empty() ? acquisition::virtualCell() : acquisition::loadCellConfig(opt->file);
    if (opt->quiet) return 0;
    std::fputs(acquisition::describeCellConfig(cell).c_str(), stdout);
    printSummary(cell);
    return 0;
  };
}

}  // namespace stampscan::station
