#include "report_document.hpp"

#include "fld_drawing.hpp"

#include <cairo-pdf.h>

#include <cmath>
#include <cstdio>

namespace stampscan::report::draw {

namespace {

constexpr double kMargin = 40;

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string orNotRecorded(const std::string& s) { return s.empty() ? "not recorded" : s; }

// Breaks `s` into lines that fit `width` at the current font.
std::vector<std::string> wrap(cairo_t* cr, const std::string& s, double width, double size) {
  cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
  std::vector<std::string> lines;
  std::string line;
  std::size_t start = 0;
  while (start <= s.size()) {
    std::size_t end = s.find(' ', start);
    if (end == std::string::npos) end = s.size();
    const std::string word = s.substr(start, end - start);
    const std::string candidate = line.empty() ? word : line + " " + word;
    cairo_text_extents_t e;
    cairo_text_extents(cr, candidate.c_str(), &e);
    if (e.x_advance > width && !line.empty()) {
      lines.push_back(line);
      line = word;
    } else {
      line = candidate;
    }
    start = end + 1;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

double paragraph(cairo_t* cr, double x, double y, double width, const std::string& s, double size) {
  for (const std::string& line : wrap(cr, s, width, size)) {
    text(cr, x, y, line, size);
    y += size * 1.35;
  }
  return y;
}

void footer(cairo_t* cr, const ReportContent& c, int page, int pages) {
  setGrey(cr, 0.45);
  text(cr, kMargin, kA4Height - 24, "StampScan forming analysis, part " + c.run->part_id + ", " + c.generated, 7.5);
  text(cr, kA4Width - kMargin, kA4Height - 24, "page " + std::to_string(page) + " of " + std::to_string(pages), 7.5,
       Align::Right);
}

void table(cairo_t* cr, double x, double y, const std::vector<double>& widths, const std::vector<std::string>& header,
           const std::vector<std::vector<std::string>>& rows, double size) {
  const double row_h = size * 1.6;
  double width = 0;
  for (const double w : widths) width += w;
  setGrey(cr, 0.9);
  cairo_rectangle(cr, x, y, width, row_h);
  cairo_fill(cr);
  setGrey(cr, 0.1);
  double cx = x;
  for (std::size_t i = 0; i < header.size(); ++i) {
    text(cr, cx + 3, y + row_h * 0.7, header[i], size, Align::Left, true);
    cx += widths[i];
  }
  y += row_h;
  cairo_set_line_width(cr, 0.4);
  for (const auto& row : rows) {
    cx = x;
    setGrey(cr, 0.1);
    for (std::size_t i = 0; i < row.size() && i < widths.size(); ++i) {
      text(cr, cx + 3, y + row_h * 0.7, row[i], size);
      cx += widths[i];
    }
    setGrey(cr, 0.8);
    cairo_move_to(cr, x, y + row_h);
    cairo_line_to(cr, x + width, y + row_h);
    cairo_stroke(cr);
    y += row_h;
  }
}

void summaryPage(cairo_t* cr, const ReportContent& c) {
  const StrainAnalysis& a = *c.analysis;
  setGrey(cr, 0.1);
  text(cr, kMargin, 58, "Forming analysis: part " + c.run->part_id, 17, Align::Left, true);
  double y = 82;
  for (const auto& [label, value] : runFacts(c)) {
    setGrey(cr, 0.35);
    text(cr, kMargin, y, label, 8.5, Align::Left, true);
    setGrey(cr, 0.1);
    y = paragraph(cr, kMargin + 85, y, kA4Width - 2 * kMargin - 85, value, 8.5) + 1.5;
  }
  // The verdict.
  y += 4;
  setColour(cr, verdictColour(a.verdict));
  cairo_rectangle(cr, kMargin, y, kA4Width - 2 * kMargin, 42);
  cairo_fill(cr);
  cairo_set_source_rgb(cr, 1, 1, 1);
  text(cr, kMargin + 10, y + 18, "Verdict: " + upper(toString(a.verdict)), 14, Align::Left, true);
  const auto reason = wrap(cr, a.verdict_reason, kA4Width - 2 * kMargin - 20, 8);
  for (std::size_t i = 0; i < reason.size() && i < 2; ++i)
    text(cr, kMargin + 10, y + 30 + 9.5 * static_cast<double>(i), reason[i], 8);
  y += 52;
  std::string zones;
  for (std::size_t z = 0; z < kZoneCount; ++z)
    zones += (z ? ", " : "") + std::string(toString(static_cast<Zone>(z))) + " " + std::to_string(a.zone_counts[z]);
  setGrey(cr, 0.1);
  char figures[200];
  std::snprintf(figures, sizeof figures, "max thinning %s%%, min safety margin %s%%; ",
                formatPercent(a.max_thinning_percent).c_str(), formatPercent(a.min_margin_percent).c_str());
  y = paragraph(cr, kMargin, y + 4, kA4Width - 2 * kMargin, std::string(figures) + "elements by zone: " + zones, 8.5);

  // The FLD, as vectors.
  const double plot_top = y + 10;
  const FldAxes axes = fldAxes(a, *c.material, kMargin + 38, plot_top, 300, 270);
  fld(cr, axes, a, *c.material, kMargin + 365, plot_top, 0.62);
  y = plot_top + 270 + 40;

  setGrey(cr, 0.1);
  text(cr, kMargin, y, "Worst spots (lowest safety margin first; marked on the maps)", 10, Align::Left, true);
  table(cr, kMargin, y + 6, {18, 118, 50, 50, 52, 52, 80, 95}, worstSpotHeader(), worstSpotRows(a), 7.5);
}

void mapSection(cairo_t* cr, const ReportContent& c, std::size_t quantity, double top) {
  const auto views = standardViews();
  const ColourScale& scale = (*c.scales)[quantity];
  setGrey(cr, 0.1);
  text(cr, kMargin, top + 12, std::string(caption(kMapQuantities[quantity])) + " (" + scale.unit() + ")", 12,
       Align::Left, true);
  const double cell_w = 208, cell_h = 165, gap = 6;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const MapRaster& map = (*c.maps)[quantity * views.size() + v];
    const double x = kMargin + static_cast<double>(v % 2) * (cell_w + gap);
    const double y = top + 20 + static_cast<double>(v / 2) * (cell_h + gap);
    setGrey(cr, 0.85);
    cairo_set_line_width(cr, 0.5);
    cairo_rectangle(cr, x, y, cell_w, cell_h);
    cairo_stroke(cr);
    placeMap(cr, map, x + 2, y + 2, cell_w - 4, cell_h - 16, 4.5);
  }
  colourBar(cr, kMargin + 2 * cell_w + gap + 14, top + 26, 80, 2 * cell_h - 10, scale);
}

void notesSection(cairo_t* cr, const ReportContent& c, double top) {
  const Material& m = *c.material;
  setGrey(cr, 0.1);
  text(cr, kMargin, top + 12, "How to read this report", 12, Align::Left, true);
  const double width = kA4Width - 2 * kMargin;
  double y = top + 30;
  char margin[64];
  std::snprintf(margin, sizeof margin, "%.0f%%", m.safety_margin_percent);
  const std::vector<std::string> notes = {
      "Strains are measured on the printed grid: each element's major (e1) and minor (e2) strain, in engineering "
      "strain "
      "%, and its thinning (1 - exp(eps3)) x 100, where eps3 is the thickness true strain.",
      "The safety margin is the distance from an element to the forming-limit curve along the element's strain path "
      "(the "
      "line from the origin of the diagram through the element), in engineering strain %. Negative: above the curve.",
      std::string("Zones: failure on or above the FLC; marginal within the ") + margin +
          " safety margin below it; wrinkling where the sheet thickened and was compressed at least as hard as in "
          "uniaxial compression; wrinkling tendency where it thickened less; insufficient stretch where the major "
          "strain "
          "stayed under the stretch threshold; safe otherwise.",
      "Verdict: failed when a patch of neighbouring failure elements reaches the minimum patch size, marginal when a "
      "patch of failure or marginal elements does, good otherwise. A single element above the curve is listed among "
      "the "
      "worst spots but does not decide the verdict: a lone outlier is usually a grid measurement, not a split.",
      "FLC: " + m.flc.describe() +
          (m.flc.isMeasured() ? " (the material's measured curve)."
                              : ". Keeler-Brazier (1975): FLC0 = (23.3 + 14.13 t) n / 0.21 % for t in mm (t capped at "
                                "3 mm); left branch along constant thickness, right branch of slope 0.6."),
  };
  for (const std::string& note : notes) y = paragraph(cr, kMargin, y, width, note, 8.5) + 5;
}

}  // namespace

Rgb verdictColour(Verdict v) {
  switch (v) {
    case Verdict::Good: return zoneColour(Zone::Safe);
    case Verdict::Marginal: return zoneColour(Zone::Marginal);
    case Verdict::Failed: return zoneColour(Zone::Failure);
  }
  return {0, 0, 0};
}

std::string formatPercent(double value, int decimals) {
  if (!std::isfinite(value)) return value > 0 ? "no limit" : "-";
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return text;
}

std::vector<std::pair<std::string, std::string>> runFacts(const ReportContent& c) {
  const Material& m = *c.material;
  const StrainAnalysis& a = *c.analysis;
  char material[256];
  std::snprintf(material, sizeof material, "%s (%s, t = %.2f mm, n = %.2f; FLC %s; safety margin %.0f%%)",
                m.name.c_str(), toString(m.family), m.thickness_mm, m.n, m.flc.describe().c_str(),
                m.safety_margin_percent);
  char elements[128];
  std::snprintf(elements, sizeof elements, "%zu grid elements, pitch %.2f mm", a.elements.size(), a.grid_pitch_mm);
  std::vector<std::pair<std::string, std::string>> facts = {
      {"Part id", orNotRecorded(c.run->part_id)},
      {"Part program", c.run->part_program.empty() ? "none (a plan of its own)" : c.run->part_program},
      {"Press program", c.program.empty() ? "not given" : c.program},
      {"Material", std::string(material) + (c.material_note.empty() ? "" : "; " + c.material_note)},
      {"Scanned", orNotRecorded(c.run->date)},
      {"Cell", orNotRecorded(c.run->cell)},
      {"Calibration", orNotRecorded(c.run->calibration)},
      {"Plan", orNotRecorded(c.run->plan)},
      {"Elements", elements},
  };
  if (!c.run->accuracy.empty()) facts.emplace_back("Accuracy", c.run->accuracy);
  facts.emplace_back("Report", c.generated);
  return facts;
}

std::vector<std::string> worstSpotHeader() {
  return {"#", "position x, y, z (mm)", "e1 %", "e2 %", "thinning %", "margin %", "zone", "patch"};
}

std::vector<std::vector<std::string>> worstSpotRows(const StrainAnalysis& a) {
  std::vector<std::vector<std::string>> rows;
  for (std::size_t i = 0; i < a.worst_spots.size(); ++i) {
    const WorstSpot& s = a.worst_spots[i];
    const ElementStrain& e = a.elements[s.element];
    char position[96];
    std::snprintf(position, sizeof position, "%.1f, %.1f, %.1f", e.position.x(), e.position.y(), e.position.z());
    std::string patch = "-";
    if (s.patch_size > 0)
      patch = std::to_string(s.patch_size) + (s.patch_size == 1 ? " element" : " elements") +
              (s.counted ? "" : " (ignored)");
    rows.push_back({std::to_string(i + 1), position, formatPercent(e.major_percent), formatPercent(e.minor_percent),
                    formatPercent(e.thinning_percent), formatPercent(e.margin_percent), toString(e.zone), patch});
  }
  return rows;
}

void writePdf(const std::filesystem::path& file, const ReportContent& c) {
  Surface surface(cairo_pdf_surface_create(file.c_str(), kA4Width, kA4Height));
  check(surface.get(), file.string());
  cairo_pdf_surface_set_metadata(surface.get(), CAIRO_PDF_METADATA_TITLE,
                                 ("Forming analysis, part " + c.run->part_id).c_str());
  cairo_pdf_surface_set_metadata(surface.get(), CAIRO_PDF_METADATA_CREATOR, "StampScan station report");
  Context cr = contextFor(surface.get());
  constexpr int kPages = 3;
  summaryPage(cr.get(), c);
  footer(cr.get(), c, 1, kPages);
  cairo_show_page(cr.get());
  mapSection(cr.get(), c, 0, 40);
  mapSection(cr.get(), c, 1, 420);
  footer(cr.get(), c, 2, kPages);
  cairo_show_page(cr.get());
  mapSection(cr.get(), c, 2, 40);
  notesSection(cr.get(), c, 420);
  footer(cr.get(), c, 3, kPages);
  cairo_show_page(cr.get());
  check(cr.get(), file.string());
  cr.reset();
  cairo_surface_finish(surface.get());
  check(surface.get(), file.string());
}

}  // namespace stampscan::report::draw
