#include "fld_drawing.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace stampscan::report {

Rgb zoneColour(Zone zone) {
  switch (zone) {
    case Zone::Failure: return {220, 0, 0};
    case Zone::Marginal: return {255, 170, 0};
    case Zone::Safe: return {30, 160, 60};
    case Zone::InsufficientStretch: return {150, 150, 150};
    case Zone::WrinklingTendency: return {90, 160, 230};
    case Zone::Wrinkling: return {120, 40, 200};
  }
  return {0, 0, 0};
}

FldAxes fldAxes(const StrainAnalysis& a, const Material& material, double x, double y, double w, double h) {
  FldAxes axes;
  double minor_lo = -30, minor_hi = 30, major_lo = -10, major_hi = material.flc.flc0() + 25;
  for (const ElementStrain& e : a.elements) {
    minor_lo = std::min(minor_lo, e.minor_percent - 5);
    minor_hi = std::max(minor_hi, e.minor_percent + 5);
    major_lo = std::min(major_lo, e.major_percent - 5);
    major_hi = std::max(major_hi, e.major_percent + 5);
  }
  // Round outwards to 10%, and keep wild values (a bad element) from squeezing the diagram.
  axes.minor_min = std::max(-80.0, std::floor(minor_lo / 10) * 10);
  axes.minor_max = std::min(100.0, std::ceil(minor_hi / 10) * 10);
  axes.major_min = std::max(-40.0, std::floor(major_lo / 10) * 10);
  axes.major_max = std::min(150.0, std::ceil(major_hi / 10) * 10);
  axes.x = x;
  axes.y = y;
  axes.width = w;
  axes.height = h;
  return axes;
}

FldAxes fldPngAxes(const StrainAnalysis& a, const Material& material) {
  using L = FldLayout;
  return fldAxes(a, material, L::plot_x, L::plot_y, L::plot_width, L::plot_height);
}

namespace draw {

namespace {

void polyline(cairo_t* cr, const FldAxes& axes, const std::vector<FldPoint>& points) {
  bool first = true;
  for (const FldPoint& p : points) {
    if (!std::isfinite(p.major)) continue;
    const Eigen::Vector2d d = axes.toDrawing(p.minor, p.major);
    if (first)
      cairo_move_to(cr, d.x(), d.y());
    else
      cairo_line_to(cr, d.x(), d.y());
    first = false;
  }
  cairo_stroke(cr);
}

// A proportional strain path from the origin, eps2 = beta * eps1 in true strain (a curve in the
// engineering diagram), drawn as far as the plot shows it.
void referencePath(cairo_t* cr, const FldAxes& axes, double beta, const std::string& label, double unit) {
  std::vector<FldPoint> line;
  for (int i = 0; i <= 200; ++i) {
    const double eps1 = 1.5 * i / 200.0;
    const FldPoint p{engineeringPercent(beta * eps1), engineeringPercent(eps1)};
    if (p.major > axes.major_max || p.minor < axes.minor_min || p.minor > axes.minor_max) break;
    line.push_back(p);
  }
  if (line.size() < 2) return;
  polyline(cr, axes, line);
  const Eigen::Vector2d at = axes.toDrawing(line.back().minor, line.back().major);
  // Labels at the path's end, inside the plot (the right-hand paths end at its right edge).
  if (beta > 0)
    text(cr, at.x() - 4 * unit, at.y() + 12 * unit, label, 11 * unit, Align::Right);
  else
    text(cr, at.x() + 3 * unit, at.y() + 10 * unit, label, 11 * unit);
}

// The grid every 10 % with its labels, the axes through the origin and the axes' titles.
void fldGrid(cairo_t* cr, const FldAxes& axes, double size, double unit) {
  cairo_set_line_width(cr, 0.7 * unit);
  for (double v = axes.minor_min; v <= axes.minor_max + 1e-9; v += 10) {
    const Eigen::Vector2d p = axes.toDrawing(v, axes.major_min);
    setGrey(cr, v == 0 ? 0.35 : 0.88);
    cairo_move_to(cr, p.x(), axes.y);
    cairo_line_to(cr, p.x(), axes.y + axes.height);
    cairo_stroke(cr);
    setGrey(cr, 0.15);
    char label[16];
    std::snprintf(label, sizeof label, "%.0f", v);
    text(cr, p.x(), axes.y + axes.height + size * 1.3, label, size, Align::Centre);
  }
  for (double v = axes.major_min; v <= axes.major_max + 1e-9; v += 10) {
    const Eigen::Vector2d p = axes.toDrawing(axes.minor_min, v);
    setGrey(cr, v == 0 ? 0.35 : 0.88);
    cairo_move_to(cr, axes.x, p.y());
    cairo_line_to(cr, axes.x + axes.width, p.y());
    cairo_stroke(cr);
    setGrey(cr, 0.15);
    char label[16];
    std::snprintf(label, sizeof label, "%.0f", v);
    text(cr, axes.x - size * 0.4, p.y() + size * 0.35, label, size, Align::Right);
  }
  setGrey(cr, 0.1);
  text(cr, axes.x + axes.width / 2, axes.y + axes.height + size * 2.8, "minor strain e2 (engineering, %)", size * 1.05,
       Align::Centre, true);
  cairo_save(cr);
  cairo_translate(cr, axes.x - size * 2.6, axes.y + axes.height / 2);
  cairo_rotate(cr, -M_PI / 2);
  text(cr, 0, 0, "major strain e1 (engineering, %)", size * 1.05, Align::Centre, true);
  cairo_restore(cr);
}

// Inside the axes: the reference strain paths, the elements (safest first, so that the critical
// ones stay on top), the FLC and its margin curve.
void fldPlot(cairo_t* cr, const FldAxes& axes, const StrainAnalysis& a, const Material& material, double unit) {
  cairo_save(cr);
  cairo_rectangle(cr, axes.x, axes.y, axes.width, axes.height);
  cairo_clip(cr);
  // Uniaxial tension, equibiaxial stretch, pure shear (no thickness change) and uniaxial compression
  // (the wrinkling boundary).
  cairo_set_line_width(cr, 0.8 * unit);
  setGrey(cr, 0.6);
  const double dash[] = {3 * unit, 3 * unit};
  cairo_set_dash(cr, dash, 2, 0);
  referencePath(cr, axes, -0.5, "uniaxial", unit);
  referencePath(cr, axes, 1.0, "equibiaxial", unit);
  referencePath(cr, axes, -1.0, "pure shear", unit);
  referencePath(cr, axes, -2.0, "uniaxial compression", unit);
  cairo_set_dash(cr, nullptr, 0, 0);

  const double dot = 2.2 * unit;
  for (const Zone z : {Zone::InsufficientStretch, Zone::Safe, Zone::WrinklingTendency, Zone::Wrinkling, Zone::Marginal,
                       Zone::Failure}) {
    setColour(cr, zoneColour(z));
    for (const ElementStrain& e : a.elements) {
      if (e.zone != z) continue;
      const Eigen::Vector2d p = axes.toDrawing(e.minor_percent, e.major_percent);
      cairo_rectangle(cr, p.x() - dot / 2, p.y() - dot / 2, dot, dot);
    }
    cairo_fill(cr);
  }

  // The FLC and the margin curve over the whole minor range shown (the margin curve's points lie
  // inwards of the FLC points they come from, so its samples reach further out).
  const int samples = 400;
  const double reach = 0.5 * (axes.minor_max - axes.minor_min);
  cairo_set_line_width(cr, 2.2 * unit);
  cairo_set_source_rgb(cr, 0, 0, 0);
  polyline(cr, axes, material.flc.sample(std::max(axes.minor_min, -95.0), axes.minor_max, samples));
  cairo_set_line_width(cr, 1.6 * unit);
  setColour(cr, {200, 110, 0});
  const double margin_dash[] = {8 * unit, 4 * unit};
  cairo_set_dash(cr, margin_dash, 2, 0);
  polyline(cr, axes,
           material.flc.marginCurve(material.safety_margin_percent, std::max(axes.minor_min - reach, -95.0),
                                    axes.minor_max + reach, samples));
  cairo_set_dash(cr, nullptr, 0, 0);
  cairo_restore(cr);
  setGrey(cr, 0.2);
  cairo_set_line_width(cr, 1.0 * unit);
  cairo_rectangle(cr, axes.x, axes.y, axes.width, axes.height);
  cairo_stroke(cr);
}

// The legend: the material, the two curves and the count of each zone.
void fldLegend(cairo_t* cr, const StrainAnalysis& a, const Material& material, double legend_x, double legend_y,
               double size, double unit) {
  double y = legend_y + size;
  setGrey(cr, 0.1);
  text(cr, legend_x, y, material.name + " (" + toString(material.family) + ")", size * 1.05, Align::Left, true);
  char line[160];
  std::snprintf(line, sizeof line, "t = %.2f mm, n = %.2f", material.thickness_mm, material.n);
  y += size * 1.5;
  text(cr, legend_x, y, line, size);
  y += size * 1.5;
  text(cr, legend_x, y, "FLC: " + material.flc.describe(), size);
  y += size * 2.2;
  cairo_set_line_width(cr, 2.2 * unit);
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_move_to(cr, legend_x, y - size * 0.35);
  cairo_line_to(cr, legend_x + size * 2, y - size * 0.35);
  cairo_stroke(cr);
  text(cr, legend_x + size * 2.6, y, "forming-limit curve", size);
  y += size * 1.6;
  setColour(cr, {200, 110, 0});
  cairo_set_line_width(cr, 1.6 * unit);
  const double margin_dash[] = {8 * unit, 4 * unit};
  cairo_set_dash(cr, margin_dash, 2, 0);
  cairo_move_to(cr, legend_x, y - size * 0.35);
  cairo_line_to(cr, legend_x + size * 2, y - size * 0.35);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  setGrey(cr, 0.1);
  std::snprintf(line, sizeof line, "safety margin, %.0f%%", material.safety_margin_percent);
  text(cr, legend_x + size * 2.6, y, line, size);
  y += size * 2.2;
  for (std::size_t z = 0; z < kZoneCount; ++z) {
    const Zone zone = static_cast<Zone>(z);
    setColour(cr, zoneColour(zone));
    cairo_rectangle(cr, legend_x, y - size * 0.8, size * 0.9, size * 0.9);
    cairo_fill(cr);
    setGrey(cr, 0.1);
    std::snprintf(line, sizeof line, "%s: %zu", toString(zone), a.count(zone));
    text(cr, legend_x + size * 1.5, y, line, size);
    y += size * 1.55;
  }
}

}  // namespace

void fld(cairo_t* cr, const FldAxes& axes, const StrainAnalysis& a, const Material& material, double legend_x,
         double legend_y, double unit) {
  const double size = 13 * unit;
  cairo_save(cr);
  fldGrid(cr, axes, size, unit);
  fldPlot(cr, axes, a, material, unit);
  fldLegend(cr, a, material, legend_x, legend_y, size, unit);
  cairo_restore(cr);
}

std::string fldPng(const StrainAnalysis& a, const Material& material, const std::string& title) {
  using L = FldLayout;
  Surface surface = imageSurface(L::width, L::height, true);
  Context cr = contextFor(surface.get());
  setGrey(cr.get(), 0.1);
  text(cr.get(), 16, 34, title, 22, Align::Left, true);
  fld(cr.get(), fldPngAxes(a, material), a, material, L::plot_x + L::plot_width + 30, L::plot_y, 1.0);
  check(cr.get(), "drawing the forming-limit diagram");
  cairo_surface_flush(surface.get());
  return encodePng(surface.get());
}

}  // namespace draw
}  // namespace stampscan::report
