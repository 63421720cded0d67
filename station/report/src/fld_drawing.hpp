// Drawing the forming-limit diagram (fld_plot.hpp) on any cairo surface: the PNG and, as vectors,
// the PDF report.
#pragma once

#include "cairo_draw.hpp"
#include "stampscan/report/fld_plot.hpp"

#include <string>

namespace stampscan::report::draw {

// The diagram in `axes`' plot area with its tick labels and axis titles around it, and the legend
// (material, the curves, the zones with their counts) from (legend_x, legend_y). `unit` scales
// line widths and text: 1 for a PNG in pixels, about 0.6 for a PDF in points.
void fld(cairo_t* cr, const FldAxes& axes, const StrainAnalysis& analysis, const Material& material, double legend_x,
         double legend_y, double unit);

// fld.png.
std::string fldPng(const StrainAnalysis& analysis, const Material& material, const std::string& title);

}  // namespace stampscan::report::draw
