// The report of a run folder (the folder `station scan` writes: cloud4d.ply, mesh.ply, run.json):
// the forming-limit analysis of its elements, written back into the folder as
//   thinning-<view>.png, major-strain-<view>.png, safety-margin-<view>.png   (views top, front, side, oblique)
//   fld.png          the forming-limit diagram
//   report.pdf       A4, vector: the run, the verdict, the FLD, the worst spots, the maps
//   report.html      the same as one self-contained page (images embedded)
//   elements.csv     every element's strains, margin and zone
//   report.json      the verdict and the figures, for the results history
// All files are written first and then renamed into place together: a failure leaves the folder as
// it was, and a report never mixes files of two runs of the report.
#pragma once

#include "stampscan/report/material.hpp"
#include "stampscan/report/strain_analysis.hpp"

#include <array>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::report {

// A run folder that cannot be reported: names the file or the material and what is wrong.
class ReportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ReportOptions {
  std::string material;                        // empty: run.json's "material", else kDefaultMaterial
  std::string program;                         // the press program; empty: run.json's "program"
  const MaterialLibrary* materials = nullptr;  // borrowed for the call; null: the built-in library
  AnalysisParams analysis;
};

// What run.json says about the run (every field optional; "" when absent).
struct RunInfo {
  std::string part_id, program, plan, cell, date, calibration, material;
  std::string part_program;  // the part program scanned (its name, the part number); empty: none
  std::string accuracy;  // on the virtual cell: the accuracy against the simulated part
  std::string data_loss;  // what the scan lacks (run.json data_loss); empty when it measured all it should
};

// Where the material of a report came from.
enum class MaterialSource { Option, RunJson, Default };
const char* toString(MaterialSource source);  // "option", "run.json", "default"

struct ReportSummary {
  std::filesystem::path run_dir;
  std::vector<std::filesystem::path> files;  // written, in the order listed above
  RunInfo run;
  std::string material;  // the material used
  MaterialSource material_source = MaterialSource::Default;
  bool drawn_from_mesh = true;  // the maps show mesh.ply; without one, the elements of cloud4d.ply
  Verdict verdict = Verdict::Good;
  std::string verdict_reason;
  std::size_t elements = 0;           // judged
  std::size_t elements_left_out = 0;  // invalid, left out (AnalysisParams::leave_out_invalid)
  std::array<std::size_t, kZoneCount> zone_counts{};
  double max_thinning_percent = 0;
  double min_margin_percent = 0;
  double seconds = 0;          // all of it
  double drawing_seconds = 0;  // images, PDF and HTML
};

// Throws ReportError (missing or damaged cloud4d.ply, damaged mesh.ply or run.json, unknown material)
// or std::runtime_error naming the file that could not be written.
ReportSummary writeRunReport(const std::filesystem::path& run_dir, const ReportOptions& options = {});

// The run.json fields a report shows; a missing file gives an empty RunInfo. Throws ReportError
// naming the file when it is not valid JSON.
RunInfo readRunInfo(const std::filesystem::path& run_dir);

}  // namespace stampscan::report
