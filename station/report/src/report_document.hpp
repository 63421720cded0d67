// The report documents: the PDF (A4, vector text and FLD, the maps as embedded images) and the
// self-contained HTML page, from one description of their content.
#pragma once

#include "stampscan/report/colour_scale.hpp"
#include "stampscan/report/run_report.hpp"
#include "strain_map_drawing.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace stampscan::report::draw {

struct ReportContent {
  const RunInfo* run = nullptr;
  std::string program;  // as shown
  const Material* material = nullptr;
  std::string material_note;  // where the material came from
  const StrainAnalysis* analysis = nullptr;
  std::string generated;  // the report's own date and time
  // The maps, quantity by quantity (kMapQuantities order), each in standardViews() order, and the
  // scale of each quantity.
  const std::vector<MapRaster>* maps = nullptr;
  const std::vector<ColourScale>* scales = nullptr;
};

// A4 portrait in points.
inline constexpr double kA4Width = 595.276, kA4Height = 841.890;

// Writes the PDF to `file` (the caller's temporary). Throws naming the file on failure.
void writePdf(const std::filesystem::path& file, const ReportContent& content);

// The HTML page; `images` are the PNG files by name, embedded as data URIs.
std::string html(const ReportContent& content, const std::vector<std::pair<std::string, const std::string*>>& images);

Rgb verdictColour(Verdict verdict);

// Table rows shared by both documents.
std::vector<std::pair<std::string, std::string>> runFacts(const ReportContent& content);
std::vector<std::vector<std::string>> worstSpotRows(const StrainAnalysis& analysis);
std::vector<std::string> worstSpotHeader();
std::string formatPercent(double value, int decimals = 1);

}  // namespace stampscan::report::draw
