// The forming-limit diagram of a part: every element as a point coloured by its zone, the FLC and
// the margin curve, axes in engineering strain percent. The axes' placement is public, so that a
// point of the diagram can be found in the image.
#pragma once

#include "stampscan/report/colour_scale.hpp"
#include "stampscan/report/strain_analysis.hpp"

#include <Eigen/Core>

namespace stampscan::report {

// The colour of each zone on the FLD and in the tables.
Rgb zoneColour(Zone zone);

// The plot area of an FLD and the strain ranges it shows.
struct FldAxes {
  double minor_min = -40, minor_max = 40, major_min = -10, major_max = 60;  // engineering %
  double x = 0, y = 0, width = 1, height = 1;                               // the plot area, drawing units
  // Drawing coordinates of a point of the diagram (y grows downwards).
  Eigen::Vector2d toDrawing(double minor_percent, double major_percent) const {
    return {x + (minor_percent - minor_min) / (minor_max - minor_min) * width,
            y + (major_max - major_percent) / (major_max - major_min) * height};
  }
};

// Ranges that hold the FLC around plane strain and the elements (round to 10%), placed in the
// plot area (x, y, w, h).
FldAxes fldAxes(const StrainAnalysis& analysis, const Material& material, double x, double y, double w, double h);

// fld.png: the image size and where the axes sit in it.
struct FldLayout {
  static constexpr int width = 1100, height = 800;
  static constexpr int plot_x = 90, plot_y = 60, plot_width = 700, plot_height = 660;
};
FldAxes fldPngAxes(const StrainAnalysis& analysis, const Material& material);

}  // namespace stampscan::report
