// `station report RUN_DIR`: the forming-limit analysis and report of a run folder, written into it.
// A thin caller of report::writeRunReport (station/report/), which `station scan` calls as well.
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/report/run_report.hpp"
#include "stampscan/results/run_recording.hpp"
#include "stampscan/station/commands.hpp"

#include <cmath>
#include <cstdio>
#include <memory>

namespace stampscan::station {

namespace {
struct ReportCommandOptions {
  std::string run_dir, material, program, cell;
  bool list_materials = false;
  bool leave_out_invalid = false;
};

void printMaterials(const report::MaterialLibrary& library) {
  for (const report::Material& m : library.materials())
    std::printf("  %-10s %-9s t %.2f mm  n %.2f  FLC %s, margin %.0f%%\n", m.name.c_str(), report::toString(m.family),
                m.thickness_mm, m.n, m.flc.describe().c_str(), m.safety_margin_percent);
}
}  // namespace

CommandRunner addReportCommand(CLI::App& app) {
  auto opt = std::make_shared<ReportCommandOptions>();
  CLI::App* cmd = app.add_subcommand("report",
                                     "Forming analysis of a run folder: strain maps, forming-limit diagram, "
                                     "verdict, PDF and HTML report, elements.csv (written into the folder)");
  cmd->add_option("run_dir", opt->run_dir, "The run folder (RUNS/<time>-<part-id>/, with cloud4d.ply)");
  cmd->add_option(
      "--material", opt->material,
      std::string("Sheet material (default: run.json's \"material\", else ") + report::kDefaultMaterial + ")");
  cmd->add_option("--program", opt->program, "The press program, for the report (default: run.json's \"program\")");
  cmd->add_flag("--list-materials", opt->list_materials, "List the materials and exit");
  cmd->add_flag("--leave-out-invalid", opt->leave_out_invalid,
                "Judge the elements with valid strains when some are not finite or beyond any sheet's (without it "
                "such a cloud is refused); the verdict is then never good and says how many were left out");
  cmd->add_option("--cell", opt->cell,
                  "The cell file: its [report] materials are added to the built-in ones, and the run is recorded in "
                  "its [results] database");
  return [opt]() {
    // What the report takes of the cell file: the plant's materials and the results database.
    std::string materials_file, results_database;
    if (!opt->cell.empty()) {
      const acquisition::CellConfig cell = acquisition::loadCellConfig(opt->cell);
      materials_file = cell.materials_file;
      results_database = cell.results_database;
    }
    const report::MaterialLibrary materials = report::materialsWith(materials_file);
    if (opt->list_materials) {
      printMaterials(materials);
      return 0;
    }
    if (opt->run_dir.empty()) throw std::runtime_error("report: give the run folder (or --list-materials)");
    report::ReportOptions options;
    options.material = opt->material;
    options.program = opt->program;
    options.materials = &materials;
    options.analysis.leave_out_invalid = opt->leave_out_invalid;
    const report::ReportSummary s = report::writeRunReport(opt->run_dir, options);
    std::printf("station report %s\n", s.run_dir.c_str());
    std::printf("  material    %s%s\n", s.material.c_str(),
                s.material_source == report::MaterialSource::Default
                    ? " (the default: run.json names no material; choose with --material)"
                : s.material_source == report::MaterialSource::RunJson ? " (from run.json)"
                                                                       : "");
    std::printf("  surface     %s\n", s.drawn_from_mesh ? "mesh.ply" : "cloud4d.ply (the run has no mesh)");
    for (const auto& file : s.files) std::printf("  wrote       %s\n", file.filename().c_str());
    std::printf("  elements    %zu%s:", s.elements, s.elements_left_out ? " judged" : "");
    for (std::size_t z = 0; z < report::kZoneCount; ++z)
      std::printf("%s %s %zu", z ? "," : "", report::toString(static_cast<report::Zone>(z)), s.zone_counts[z]);
    if (s.elements_left_out)
      std::printf("\n  left out    %zu invalid elements (--leave-out-invalid)", s.elements_left_out);
    char margin[48] = "none (no strain path meets the FLC)";
    if (std::isfinite(s.min_margin_percent)) std::snprintf(margin, sizeof margin, "%.1f%%", s.min_margin_percent);
    std::printf("\n  figures     max thinning %.1f%%, min safety margin %s\n", s.max_thinning_percent, margin);
    std::printf("  verdict     %s: %s\n", report::toString(s.verdict), s.verdict_reason.c_str());
    std::printf("  time        %.2f s (images, PDF and HTML %.2f s)\n", s.seconds, s.drawing_seconds);
    // In the cell's results database, else in the results.sqlite of the runs folder that holds the run.
    const results::RunRow recorded = results_database.empty()
                                            ? results::recordRunInResults(s.run_dir)
                                            : results::recordRunInResults(s.run_dir, results_database);
    std::printf("  recorded    %s\n", recorded.run_id.c_str());
    return 0;
  };
}

}  // namespace stampscan::station
